#!/usr/bin/env bash
# Runs every benchmark program of a build (make bench). Speed is measured
# here, never in tests; quote ratios measured within one run.
set -euo pipefail
build="${1:-build}"
mkdir -p out/bench
for exe in "$build"/bench/*/bench_*; do
  [[ -x "$exe" ]] || continue
  name="$(basename "$exe")"
  echo "== $name"
  "$exe" | tee "out/bench/$name.txt"
done
