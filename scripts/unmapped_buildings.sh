#!/usr/bin/env bash
# Each real building's whole raw log localized in a map of the other buildings
# (the four other logs with ground truth and the eight Radish buildings), so
# every estimate is wrong: the flag must never rise, and a calibrated
# confidence value stays near 0. Writes OUT/BUILDING.tum.csv (localize --out)
# and OUT/BUILDING.json; scripts/confidence_fit.py --unmapped OUT reads them.
#
#   scripts/unmapped_buildings.sh OUT [BUILDING...]     (LSHLOC, LSHLOC_DATA as elsewhere)
set -euo pipefail
out=${1:?usage: scripts/unmapped_buildings.sh OUT [BUILDING...]}
shift
here=$(cd "$(dirname "$0")/.." && pwd)
lshloc=${LSHLOC:-$here/build/bin/lshloc}
data=${LSHLOC_DATA:-$here/../shared/data}
[ -d "$data" ] || { echo "unmapped_buildings: no data directory $data" >&2; exit 1; }
corrected() {
  case $1 in
    fr079) echo "$data/fr079/fr079-complete.gfs.log.gz" ;;
    intel) echo "$data/intel/intel.gfs.log.gz" ;;
    fr101) echo "$data/fr101/fr101.carmen.gfs.log.gz" ;;
    aces) echo "$data/aces/aces-corrected.log.gz" ;;
    mit-csail) echo "$data/mit-csail/csail.corrected.log.gz" ;;
  esac
}
raw() {
  case $1 in
    fr079) echo "$data/fr079/fr079.recon-from-bag.log.gz" ;;
    intel) echo "$data/intel/intel.recon-from-bag.log.gz" ;;
    fr101) echo "$data/fr101/fr101.carmen.log.gz" ;;
    aces) echo "$data/aces/aces.recon-from-bag.log.gz" ;;
    mit-csail) echo "$data/mit-csail/mit-csail.clf.gz" ;;
  esac
}
all=(fr079 intel fr101 aces mit-csail)
[ $# -gt 0 ] || set -- "${all[@]}"
mkdir -p "$out"
for b in "$@"; do
  [ -n "$(raw "$b")" ] || { echo "unmapped_buildings: unknown building $b (one of ${all[*]})" >&2; exit 1; }
  maps=()
  for o in "${all[@]}"; do [ "$o" = "$b" ] || maps+=(--map "$(corrected "$o")"); done
  for r in "$data"/radish-gfs-corrected/*.log.gz; do maps+=(--map "$r"); done
  echo "unmapped_buildings: $b in a map of $(( ${#maps[@]} / 2 )) other buildings" >&2
  "$lshloc" localize "${maps[@]}" --target "$(raw "$b")" --out "$out/$b.tum" --json >"$out/$b.json"
done
