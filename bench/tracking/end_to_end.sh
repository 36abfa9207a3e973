#!/usr/bin/env bash
# The tracker end to end, as a user runs it (issue 23, "Speed"): a synthetic Brownian
# slab video written as 300 RGBA PNG frames of 640 x 424 px with ~600 particles
# (`mmval synth --scene brownian-slab --format rgba`, its defaults: 24 fps, 0.15 um/px,
# seed 1), tracked by `mmval track` with default settings, process start to the last
# output file. Prints every run's wall, user and system time, the fastest wall time and
# the median CPU time; then the pure-decoding bench of the same files
# (bench_tracking_decode: cv::imread, the tracker's own reader on 1 and N threads), the
# run's stage budget (wall and CPU per stage), its decoding share and detection + linking
# alone on frames held in memory. Never asserts on time; the machine's load changes wall
# times (CPU time is the steadier measure).
#
# Usage: bench/tracking/end_to_end.sh [BUILD_DIR] [WORK_DIR] [RUNS] [THREADS]
#   BUILD_DIR  a built tree (mmval and bench_tracking_decode), default build
#   WORK_DIR   where the video and the outputs go, default ${TMPDIR:-/tmp}/mmval-end-to-end
#   RUNS       timed runs of mmval track, default 5
#   THREADS    --threads of mmval track and the bench's N, default 0 (every core) / nproc
set -euo pipefail
build="${1:-build}"
work="${2:-${TMPDIR:-/tmp}/mmval-end-to-end}"
runs="${3:-5}"
threads="${4:-0}"
mmval="$build/bin/mmval"
bench="$build/bench/tracking/bench_tracking_decode"
for exe in "$mmval" "$bench"; do
  [[ -x "$exe" ]] || { echo "missing $exe: build the targets mmval and bench_tracking_decode first" >&2; exit 1; }
done
mkdir -p "$work"
video="$work/rgba-300"
if [[ ! -f "$video/truth.csv" ]]; then
  "$mmval" synth --scene brownian-slab --format rgba --out "$video" >&2
fi
frames="$video/frames"
out="$work/out"
echo "== mmval track $frames --pixel-size-um 0.15 --fps 24 --threads $threads --out $out --quiet ($runs runs)"
TIMEFORMAT='%R %U %S'
times=()
for ((k = 0; k < runs; ++k)); do
  t=$({ time "$mmval" track "$frames" --pixel-size-um 0.15 --fps 24 --threads "$threads" --out "$out" --quiet > /dev/null; } 2>&1 | tail -n 1)
  echo "run $((k + 1)): wall user sys (s) = $t"
  times+=("$t")
done
printf '%s\n' "${times[@]}" | python3 -c '
import statistics, sys
rows = [list(map(float, line.split())) for line in sys.stdin if line.strip()]
wall = min(r[0] for r in rows)
cpu = statistics.median(r[1] + r[2] for r in rows)
print(f"end to end: fastest wall {wall:.3f} s (min of {len(rows)}), median CPU (user + sys) {cpu:.3f} s")
'
python3 - "$out/summary.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
b = d.get("brownian", {})
print(f"summary.json: motion {d['motion']['model']}, D {b.get('D_um2_per_s', float('nan')):.4f} um^2/s, exponent {b.get('alpha', float('nan')):.3f}, "
      f"tracker (runTracker) {d['seconds']:.3f} s")
PY
nproc_n="$threads"
[[ "$nproc_n" == 0 ]] && nproc_n="$(nproc)"
echo "== bench_tracking_decode --frames 300 --threads $nproc_n (same files)"
"$bench" --frames 300 --threads "$nproc_n" --dir "$work" --formats rgba
