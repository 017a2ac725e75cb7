#!/usr/bin/env bash
# A robot outside a small map: windows of each real building's raw log
# localized in a map of ONE other building (fr079, fr101, intel, aces,
# mit-csail, each from its corrected log), so every estimate is wrong and the
# flag must stay down. A map of one building holds few look-alikes to rival
# the best place, so this is where the flag's margin test is weakest
# (docs/results/confidence.md, "A robot outside a small map").
# Writes OUT/TARGET_in_MAP_START.json (localize --json) and prints one line per
# flagged window and a summary line.
#
#   scripts/eval/unmapped_small_maps.sh OUT [--config FILE] [--windows N] [--length L]
#   (LSHLOC, LSHLOC_DATA as elsewhere; JOBS parallel runs, default 2)
set -euo pipefail
out=${1:?usage: scripts/eval/unmapped_small_maps.sh OUT [--config FILE] [--windows N] [--length L]}
shift
config="" windows=6 length=300
while [ $# -gt 0 ]; do
  case $1 in
    --config) config=${2:?--config needs a FILE}; shift 2 ;;
    --windows) windows=${2:?--windows needs N}; shift 2 ;;
    --length) length=${2:?--length needs L}; shift 2 ;;
    *) echo "unmapped_small_maps: unknown option $1" >&2; exit 2 ;;
  esac
done
[[ $windows =~ ^[1-9][0-9]*$ && $length =~ ^[1-9][0-9]*$ ]] ||
  { echo "unmapped_small_maps: --windows and --length take positive integers" >&2; exit 2; }
here=$(cd "$(dirname "$0")/../.." && pwd)
lshloc=${LSHLOC:-$here/build/bin/lshloc}
data=${LSHLOC_DATA:-$here/../shared/data}
[ -d "$data" ] || { echo "unmapped_small_maps: no data directory $data" >&2; exit 1; }
[ -z "$config" ] || [ -f "$config" ] || { echo "unmapped_small_maps: no config file $config" >&2; exit 1; }
mkdir -p "$out/maps"
# Every building with a raw log is a target (fr-clinic and mit-killian too:
# never in a map); the five with a corrected log are the maps.
LSHLOC_DATA="$data" "$lshloc" info --buildings | python3 -c '
import json, sys
for r in map(json.loads, sys.stdin):
    if r["raw_log"]: print(r["building"], r["raw_log"], r["corrected_log"] or "-")' >"$out/buildings.txt"
while read -r b raw corrected; do
  [ "$corrected" = - ] || [ -s "$out/maps/$b.map" ] ||
    "$lshloc" map build --out "$out/maps/$b.map" "$corrected" >/dev/null 2>&1
done <"$out/buildings.txt"
# One job per (target, map, start): start = i (N - length) / (windows - 1).
while read -r b raw _; do
  n=$("$lshloc" info "$raw" 2>/dev/null | python3 -c 'import json, sys; print(json.load(sys.stdin)["scans"])')
  for m in "$out"/maps/*.map; do
    m=$(basename "$m" .map)
    [ "$m" = "$b" ] && continue
    for ((i = 0; i < windows; i++)); do
      s=$((windows > 1 ? i * (n - length) / (windows - 1) : 0))
      echo "$b $raw $m $s"
    done
  done
done <"$out/buildings.txt" >"$out/jobs.txt"
export lshloc out config length
xargs -P "${JOBS:-2}" -L 1 bash -c '
  f=$out/$0_in_$2_$3.json
  [ -s "$f" ] || "$lshloc" localize --map "$out/maps/$2.map" --target "$1" --start "$3" --length "$length" --json \
    ${config:+--config "$config"} >"$f" 2>/dev/null || [ $? -eq 3 ] ||  # 3: not localized, as it should be here
    { echo "unmapped_small_maps: $0 in $2 at $3 failed" >&2; rm -f "$f"; }
' <"$out/jobs.txt"
python3 - "$out" <<'PY'
import glob, json, os, sys
windows = flagged = confident = scans = 0
for path in sorted(glob.glob(os.path.join(sys.argv[1], "*_in_*.json"))):
    j = json.load(open(path))
    windows += 1
    scans += j["scans"]
    confident += j["confident_scans"]
    if j["confident_scans"]:
        flagged += 1
        print(f"flagged: {os.path.basename(path)[:-5]}: {j['confident_scans']} confident scans, first at {j['first_localized_at']}")
print(json.dumps({"windows": windows, "flagged_windows": flagged, "confident_scans": confident, "scans": scans,
                  "confident_share": round(confident / scans, 5) if scans else None}))
PY
