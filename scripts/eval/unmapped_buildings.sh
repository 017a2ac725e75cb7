#!/usr/bin/env bash
# Each real building's whole raw log localized in a map of the other buildings
# (the four other logs with ground truth and the eight Radish buildings), so
# every estimate is wrong: the flag must never rise, and a calibrated
# confidence value stays near 0. Writes OUT/BUILDING.tum.csv (localize --out)
# and OUT/BUILDING.json; scripts/eval/confidence_fit.py --unmapped OUT reads them.
#
#   scripts/eval/unmapped_buildings.sh OUT [BUILDING...]     (LSHLOC, LSHLOC_DATA as elsewhere)
set -euo pipefail
out=${1:?usage: scripts/eval/unmapped_buildings.sh OUT [BUILDING...]}
shift
here=$(cd "$(dirname "$0")/../.." && pwd)
lshloc=${LSHLOC:-$here/build/bin/lshloc}
data=${LSHLOC_DATA:-$here/../shared/data}
[ -d "$data" ] || { echo "unmapped_buildings: no data directory $data" >&2; exit 1; }
# The buildings' files as the tool's dataset catalog knows them.
catalog=$(LSHLOC_DATA="$data" "$lshloc" info --buildings)
file_of() {  # file_of BUILDING FIELD: a path, or nothing
  printf '%s\n' "$catalog" | python3 -c '
import json, sys
b, field = sys.argv[1:]
for r in map(json.loads, sys.stdin):
    if r["building"] == b and r[field]: print(r[field])' "$1" "$2"
}
corrected() { file_of "$1" corrected_log; }
# The buildings known only by a corrected log (the eight Radish maps).
mapfile -t radish < <(printf '%s\n' "$catalog" | python3 -c '
import json, sys
for r in map(json.loads, sys.stdin):
    if r["corrected_log"] and not r["raw_log"]: print(r["corrected_log"])')
raw() { file_of "$1" raw_log; }
all=(fr079 intel fr101 aces mit-csail)
[ $# -gt 0 ] || set -- "${all[@]}"
mkdir -p "$out"
for b in "$@"; do
  [ -n "$(raw "$b")" ] || { echo "unmapped_buildings: unknown building $b (one of ${all[*]})" >&2; exit 1; }
  maps=()
  for o in "${all[@]}"; do [ "$o" = "$b" ] || maps+=(--map "$(corrected "$o")"); done
  for r in "${radish[@]}"; do maps+=(--map "$r"); done
  echo "unmapped_buildings: $b in a map of $(( ${#maps[@]} / 2 )) other buildings" >&2
  "$lshloc" localize "${maps[@]}" --target "$(raw "$b")" --out "$out/$b.tum" --json >"$out/$b.json" ||
    [ $? -eq 3 ]  # not localized: what a building outside the map should end as
done
