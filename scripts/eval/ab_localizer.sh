#!/usr/bin/env bash
# Alternates `lshloc eval` of one scenario between two executables, one run
# after the other, and prints each run's real time factor, ms per scan, ms
# per scan by stage and map bytes per feature, for BENCHMARKS.md's
# side-by-side speed comparisons (issue 21: "measured alternating").
#   scripts/eval/ab_localizer.sh OLD_LSHLOC NEW_LSHLOC [ROUNDS] [EVAL ARGS...]
# ROUNDS defaults to 3, the scenario to fr079 at R = 15 (what the
# scale-speed acceptance check times). Compare pairs, not the columns'
# means: the machines' speed moves between runs.
set -euo pipefail
old=$1 new=$2 rounds=${3:-3}
shift $(( $# < 3 ? $# : 3 ))
[ $# -gt 0 ] || set -- --building fr079 --submaps 15
for _ in $(seq "$rounds"); do
  for exe in "$old" "$new"; do
    "$exe" eval "$@" --json 2>/dev/null | tail -n 1 | python3 -c '
import json, sys
r = json.load(sys.stdin)
stages = " ".join(f"{k}={v:.3f}" for k, v in sorted(r["ms_per_scan_by_stage"].items()))
rt, ms, bpf = r["realtime_factor"], r["ms_per_scan"], r["bytes_per_feature"]
print(sys.argv[1], f"realtime={rt:.1f} ms_per_scan={ms:.3f}", stages, f"bytes_per_feature={bpf:.1f}")' "$exe"
  done
done
