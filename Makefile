# The two commands of README.md. Both install missing Debian packages
# (scripts/setup-deps.sh), configure a Release build in build/ and build it.
#   make validate   run the default validation cases -> out/validate/
#   make test       run the whole test suite through CTest
#   make bench      also build the benchmark programs (bench/), then run them
BUILD ?= build
JOBS ?= $(shell nproc)
OUT ?= out/validate
# Benchmark programs are built by `make bench` only (they take no part in the tests).
BENCH ?= OFF

.PHONY: deps configure build validate test bench clean

deps:
	scripts/setup-deps.sh

configure: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DMMVAL_BUILD_BENCH=$(BENCH)

build: configure
	cmake --build $(BUILD) -j$(JOBS)

validate: build
	$(BUILD)/bin/mmval validate --out $(OUT)

test: build
	ctest --test-dir $(BUILD) --output-on-failure -j$(JOBS)

bench:
	$(MAKE) build BENCH=ON
	scripts/run-benchmarks.sh $(BUILD)

clean:
	rm -rf $(BUILD) out
