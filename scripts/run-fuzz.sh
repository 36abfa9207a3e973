#!/bin/sh
# Builds the libFuzzer targets of fuzz/ with clang (AddressSanitizer +
# UndefinedBehaviorSanitizer) in their own build folder and runs each for a
# fixed time on its seed corpus (fuzz/corpus/<target>). Prints the executions
# per target and exits 1 when any target finds a crash, undefined behaviour, a
# leak, a timeout or an unexpected exception (the input is saved under
# <build>/fuzz/artifacts/<corpus>/; see fuzz/README.md to reproduce it).
#
#   scripts/run-fuzz.sh [target...]        all targets when none is named
#
# Environment:
#   MMVAL_FUZZ_SECONDS  run time per target (default 60)
#   MMVAL_FUZZ_BUILD    build folder (default build-fuzz)
#   MMVAL_FUZZ_JOBS     parallel compile jobs (default 2)
#   MMVAL_BUILD_LOCK    a lock file to hold around configure and build (flock),
#                       for machines whose cores are shared; unset: no lock
#   MMVAL_FUZZ_CMAKE_ARGS  extra configure arguments
#   CC, CXX             default clang, clang++
set -eu
cd "$(dirname "$0")/.."

seconds=${MMVAL_FUZZ_SECONDS:-60}
build=${MMVAL_FUZZ_BUILD:-build-fuzz}
jobs=${MMVAL_FUZZ_JOBS:-2}

locked() {
  if [ -n "${MMVAL_BUILD_LOCK:-}" ]; then flock "$MMVAL_BUILD_LOCK" "$@"; else "$@"; fi
}

# Release flags are not wanted: fuzz/CMakeLists.txt sets -O1 -g on what it
# instruments and -O0 on the rest ("None" adds no flags of its own).
# shellcheck disable=SC2086
mkdir -p "$build"
locked cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=None \
  -DCMAKE_C_COMPILER="${CC:-clang}" -DCMAKE_CXX_COMPILER="${CXX:-clang++}" \
  -DMMVAL_FUZZ=ON -DMMVAL_BUILD_TESTS=OFF -DMMVAL_BUILD_BENCH=OFF \
  -DMMVAL_FUZZ_SECONDS="$seconds" ${MMVAL_FUZZ_CMAKE_ARGS:-} >"$build/configure.log" 2>&1 ||
  { cat "$build/configure.log"; exit 2; }

list="$build/fuzz/targets.txt"
if [ $# -gt 0 ]; then
  wanted="$*"
else
  wanted=$(cut -d' ' -f1 "$list" | tr '\n' ' ')
fi
# One target at a time, so that one that does not compile does not stop the others.
built=""
summary=""
status=0
for target in $wanted; do
  if locked cmake --build "$build" -j"$jobs" --target "$target" >"$build/fuzz/$target.build.log" 2>&1; then
    built="$built $target"
  else
    status=1
    grep -E "error" "$build/fuzz/$target.build.log" | head -n 5
    summary="$summary$(printf '%-18s %-8s (%s)' "$target" "NO-BUILD" "$build/fuzz/$target.build.log")
"
  fi
done

export ASAN_OPTIONS="${ASAN_OPTIONS:-abort_on_error=0:detect_leaks=1:symbolize=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"

for target in $built; do
  line=$(grep "^$target " "$list") || { echo "run-fuzz: unknown target $target" >&2; exit 2; }
  max_len=$(echo "$line" | cut -d' ' -f2)
  corpus=$(echo "$line" | cut -d' ' -f3)
  work="$build/fuzz/corpus/$corpus"
  artifacts="$build/fuzz/artifacts/$corpus"
  log="$build/fuzz/$target.log"
  mkdir -p "$work" "$artifacts"
  echo "== $target: ${seconds} s, -max_len=$max_len, seeds fuzz/corpus/$corpus"
  result=ok
  "$build/bin/$target" -max_total_time="$seconds" -max_len="$max_len" -timeout=10 -rss_limit_mb=4096 \
    -print_final_stats=1 -artifact_prefix="$artifacts/" "$work" "fuzz/corpus/$corpus" >"$log" 2>&1 || result=FINDING
  # The final "#N DONE" (or, after a finding, the last "#N" status line) carries the count.
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  [ -n "$execs" ] || execs=$(sed -n 's/^#\([0-9][0-9]*\).*/\1/p' "$log" | tail -n 1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n 1)
  units=$(ls "$work" | wc -l)
  if [ "$result" = FINDING ]; then
    status=1
    grep -E "ERROR|runtime error|Assertion|terminate called|what\(\)|SUMMARY|Test unit written|deadly signal|round trip|says" "$log" | head -n 20
    echo "   full log: $log"
  fi
  summary="$summary$(printf '%-18s %-8s %10s execs %8s/s  corpus %s' "$target" "$result" "${execs:-?}" "${rate:-?}" "$units")
"
done
echo
echo "run-fuzz: ${seconds} s per target"
printf '%s' "$summary"
exit $status
