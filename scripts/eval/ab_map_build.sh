#!/usr/bin/env bash
# Alternates `lshloc map build` of one log between two executables and prints
# each run's insert CPU (features, database, grids; `map build --json`'s
# insert_cpu_s) and their sum, for BENCHMARKS.md's side-by-side comparisons.
#   scripts/eval/ab_map_build.sh OLD_LSHLOC NEW_LSHLOC [ROUNDS] [LOG]
# ROUNDS defaults to 6, LOG to fr079's corrected log in $LSHLOC_DATA
# (default ../shared/data). Compare pairs, not the columns' means: the
# machines' speed moves between runs.
set -euo pipefail
old=$1 new=$2 rounds=${3:-6}
log=${4:-${LSHLOC_DATA:-../shared/data}/fr079/fr079-complete.gfs.log.gz}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for _ in $(seq "$rounds"); do
  for exe in "$old" "$new"; do
    "$exe" map build "$log" --out "$out/map" --json 2>/dev/null | python3 -c '
import json, sys
c = json.load(sys.stdin)["insert_cpu_s"]
print(sys.argv[1], " ".join(f"{k}={v:.3f}" for k, v in sorted(c.items())), f"total={sum(c.values()):.3f}")' "$exe"
  done
done
