#!/usr/bin/env bash
# Ours and OpenFOAM on the same three case files, one after the other in one
# run (a side-by-side table): Schaefer-Turek 2D-1, the square array at
# solid fraction 0.2 and the Pore2Chip chip permeability. Prints cells, value,
# error and wall time per level from each result.json, then writes a report.
# Usage: bench/side_by_side.sh [BUILD_DIR] [OUT_DIR] [NP]
set -euo pipefail
build="${1:-build}"
out="${2:-out/side-by-side}"
np="${3:-1}"
mmval="$build/bin/mmval"
cases=(cases/fluid-schaefer-turek-2d1.toml cases/fluid-square-array-phi020.toml cases/fluid-pore2chip.toml)
rm -rf "$out"
mkdir -p "$out"
for c in "${cases[@]}"; do
  name="$(basename "$c" .toml)"
  echo "== $name: mmval" >&2
  "$mmval" run "$c" --out "$out/$name-mmval" --quiet > /dev/null || true
  echo "== $name: OpenFOAM (np $np)" >&2
  "$mmval" peer openfoam "$c" --out "$out/$name-openfoam" --np "$np" > /dev/null || true
done
"$mmval" report "$out"/*-mmval "$out"/*-openfoam --out "$out/report" > /dev/null
# One row per level: solver, cells, value, error, wall seconds, ranks.
python3 - "$out" <<'PY'
import json, pathlib, sys
print(f"{'case':<28} {'solver':<16} {'level':>5} {'cells':>9} {'value':>12} {'error %':>9} {'wall s':>8} {'ranks':>5}")
for f in sorted(pathlib.Path(sys.argv[1]).glob("*/result.json")):
    d = json.load(open(f)); det = d.get("details", {})
    solver = det.get("solver", "mmval")
    for row in det.get("ladder", []) or [dict(level=0, cells=det.get("cells"), value=d["metrics"][0]["value"] if d["metrics"] else None,
                                              error=d["metrics"][0].get("error") if d["metrics"] else None, wall_seconds=d["cost"]["wall_seconds"])]:
        err = row.get("error"); val = row.get("value")
        print(f"{d['case']['name']:<28} {solver:<16} {row.get('level', 0):>5} {row.get('cells') or 0:>9} "
              f"{val if val is None else format(val, '.6g'):>12} {'-' if err is None else format(100 * err, '.3f'):>9} "
              f"{row.get('wall_seconds', 0):>8.2f} {row.get('ranks', det.get('ranks', 1)):>5}")
    print(f"{d['case']['name']:<28} {solver:<16} total wall {d['cost']['wall_seconds']:.1f} s")
PY
