#!/usr/bin/env bash
# Reproduces the end-to-end experiment of RESULTS.md: every line is one
# `lshloc eval` JSON line, appended to results/<part>.jsonl.
#   scripts/eval/sweep.sh [PART...]   parts: grid (4 buildings x R in 1 4 9 15),
#                                grid_maps (the same with every submap rebuilt
#                                from its occupancy grid, eval --grid-maps),
#                                orders (iRANSAC order rules), ablation
#                                (database vs random hypotheses), starts
#                                (20 evenly spaced starts per building at R = 15,
#                                five buildings), starts_seeded (the same with
#                                the other buildings in seeded orders 1 and 2),
#                                live (the grid with eval --live: every submap
#                                starts empty and its mapper replays at 4x),
#                                heldout (16 windows no tuning looks at: fr079,
#                                fr101, intel and aces, 1000 scans halfway
#                                between starts 2-3, 7-8, 12-13 and 17-18, R = 15,
#                                the other buildings in seeded order 3),
#                                live_starts (20 evenly spaced starts of fr079,
#                                fr101, intel and aces at R = 15, --live),
#                                ingest (map ingest, mapper scans per CPU second,
#                                fr079 at R = 15 and 100: the map built with no
#                                localizer beside it, fed live beside the
#                                localizer on one thread, and fed by mapper
#                                threads beside the localizer's; ROUNDS rounds,
#                                default 2; run it with JOBS=1)
# Environment: LSHLOC (the executable, default build/bin/lshloc), JOBS
# (parallel runs, default 2), LSHLOC_DATA (the data directory), MAP_CACHE (a
# directory: each scenario's map is built once, saved there with
# `eval --save-map`, and loaded by every later run of the same scenario,
# e.g. the order rules and the ablation's two hypothesis sources), TRACE_DIR
# (a directory: each run also writes its per-scan trace there, `eval --trace`,
# named after its arguments; scripts/eval/confidence_fit.py reads them),
# LSHLOC_SLAM_CACHE (a directory of SLAM poses kept across sweeps; default: one
# for this sweep alone), BUILDINGS (e.g. "intel mit-csail": only those
# buildings' runs are redone; the part's other lines in results/ are kept),
# SEEDS (starts_seeded only, e.g. "2": only those seeded orders are redone).
set -euo pipefail
cd "$(dirname "$0")/../.."
LSHLOC=${LSHLOC:-build/bin/lshloc}
JOBS=${JOBS:-2}
mkdir -p results
parts=("$@")
[ ${#parts[@]} -eq 0 ] && parts=(grid orders ablation starts)

run() {  # run OUT ARGS...: one eval, its JSON line appended to OUT
  local out=$1; shift
  local line
  if [ -n "${TRACE_DIR:-}" ]; then
    set -- "$@" --trace "$TRACE_DIR/$(printf '%s ' "$@" | sed -E 's/--//g; s/[^A-Za-z0-9._-]+/_/g').csv"
  fi
  if [ -n "${MAP_CACHE:-}" ] && [[ "$*" != *--grid-maps* ]] && [[ "$*" != *--live* ]]; then  # the scenario's map: the arguments without the localizer's switches
    local key
    key=$(printf '%s ' "$@" | sed -E 's/--(order-rule|hypotheses|trace) [^ ]+//g; s/[^A-Za-z0-9._-]+/_/g')
    if [ -f "$MAP_CACHE/$key.map" ]; then set -- "$@" --load-map "$MAP_CACHE/$key.map"
    else set -- "$@" --save-map "$MAP_CACHE/$key.map"; fi
  fi
  if line=$("$LSHLOC" eval --json "$@" 2>/dev/null | tail -n 1); then
    echo "$line" >>"$out"
  else
    echo "{\"failed\": \"$*\"}" >>"$out"
  fi
}
export -f run
# The runs share the SLAM poses of the buildings without a corrected log
# (`eval --slam-cache`: R = 15 loads in a quarter of the time); a directory of
# the sweep's own unless LSHLOC_SLAM_CACHE names one to keep.
if [ -z "${LSHLOC_SLAM_CACHE:-}" ]; then
  LSHLOC_SLAM_CACHE=$(mktemp -d)
  trap 'rm -rf "$LSHLOC_SLAM_CACHE"' EXIT
fi
export LSHLOC MAP_CACHE=${MAP_CACHE:-} TRACE_DIR=${TRACE_DIR:-} LSHLOC_SLAM_CACHE
[ -n "$MAP_CACHE" ] && mkdir -p "$MAP_CACHE"
[ -n "$TRACE_DIR" ] && mkdir -p "$TRACE_DIR"

start_windows() {  # "BUILDING START LENGTH": 20 evenly spaced windows of (up to) 1000 scans per building
  while read -r b total; do
    local len=$(( total < 1000 ? total : 1000 ))
    for i in $(seq 0 19); do echo "$b $(( i * (total - len) / 19 )) $len"; done
  done <<'LIST'
fr079 4934
fr101 4758
intel 13631
aces 7374
mit-csail 1988
LIST
}

jobs_for() {  # jobs_for PART: one line per eval to run
  case $1 in
    grid)
      for b in fr079 fr101 intel aces; do for r in 1 4 9 15; do echo "results/grid.jsonl --building $b --submaps $r"; done; done ;;
    live)
      for b in fr079 fr101 intel aces; do for r in 1 4 9 15; do
        echo "results/live.jsonl --building $b --submaps $r --live"; done; done ;;
    live_starts)
      start_windows | grep -v mit-csail | while read -r b start len; do
        echo "results/live_starts.jsonl --building $b --submaps 15 --start $start --length $len --live"
      done ;;
    heldout)
      while read -r b total; do for i in 2 7 12 17; do
        echo "results/heldout.jsonl --building $b --submaps 15 --start $(( (2 * i + 1) * (total - 1000) / 38 )) --length 1000 --seed 3"
      done; done <<'LIST'
fr079 4934
fr101 4758
intel 13631
aces 7374
LIST
      ;;
    grid_maps)
      for b in fr079 fr101 intel aces; do for r in 1 4 9 15; do
        echo "results/grid_maps.jsonl --building $b --submaps $r --grid-maps"; done; done ;;
    orders)
      for b in fr079 fr101 intel aces; do for o in uniform recent fresh; do
        echo "results/orders.jsonl --building $b --submaps 4 --order-rule $o"; done; done ;;
    ablation)
      for b in fr079 fr101 intel; do for r in 1 4 15; do for h in database random; do
        echo "results/ablation.jsonl --building $b --submaps $r --hypotheses $h"; done; done; done ;;
    starts|starts_seeded)
      local seeds=(0); [ "$1" = starts_seeded ] && read -r -a seeds <<<"${SEEDS:-1 2}"
      for seed in "${seeds[@]}"; do
        start_windows | while read -r b start len; do
          echo "results/$1.jsonl --building $b --submaps 15 --start $start --length $len --seed $seed"
        done
      done ;;
    ingest)
      for round in $(seq 1 "${ROUNDS:-2}"); do for r in 15 100; do
        for mode in "--threads" "--live" "--live --threads"; do echo "results/ingest.jsonl --building fr079 --submaps $r $mode"; done
      done; done ;;
    *) echo "unknown part $1" >&2; exit 2 ;;
  esac
}

for p in "${parts[@]}"; do
  if [ -n "${BUILDINGS:-}" ] || { [ "$p" = starts_seeded ] && [ -n "${SEEDS:-}" ]; }; then
    pattern="--building ($(echo "${BUILDINGS:-[a-z0-9-]+}" | tr ' ' '|')) "
    [ -f "results/$p.jsonl" ] && python3 - "results/$p.jsonl" "${BUILDINGS:-}" "${SEEDS:-}" <<'PY'
import json, sys
path, buildings, seeds = sys.argv[1], sys.argv[2].split(), [int(s) for s in sys.argv[3].split()]
def redone(r):  # a line the rerun replaces
    return (not buildings or r.get("building") in buildings) and (not seeds or r.get("seed") in seeds)
kept = [l for l in open(path) if l.strip() and not redone(json.loads(l))]
open(path, "w").writelines(kept)
PY
    jobs_for "$p" | { grep -E -- "$pattern" || true; } | xargs -r -P "$JOBS" -I{} bash -c 'run {}'
  else
    rm -f "results/$p.jsonl"
    jobs_for "$p" | xargs -P "$JOBS" -I{} bash -c 'run {}'
  fi
  echo "$p: $(wc -l <"results/$p.jsonl") runs in results/$p.jsonl" >&2
done
