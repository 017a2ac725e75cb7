#!/usr/bin/env bash
# Writes into a "full disk": a file-size limit (ulimit -f, with SIGXFSZ
# ignored so that writes fail with EFBIG as on a full disk). Every output
# (CSV, TUM, figures, saved maps, ROS maps, simulated logs, SLAM
# trajectories) must fail with a message naming the file and a non-zero
# exit, and leave no file under its final name and no temporary file.
# Usage: full_disk_test.sh LSHLOC
set -uo pipefail
LSHLOC=$1
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$LSHLOC" simulate --out "$d/sim" --buildings 1 --seed 4 --scans 600 >/dev/null || fail "simulate"
log=$d/sim/sim-4-000/sim-4-000-corrected.log.gz raw=$d/sim/sim-4-000/sim-4-000.log.gz

# limited KB CHECKED_FILE COMMAND...: runs COMMAND under a KB-sized file limit.
limited() {
  local kb=$1 out=$2; shift 2
  mkdir -p "$d/out"
  ( trap '' XFSZ; ulimit -f "$kb"; "$@" ) >/dev/null 2>"$d/err.txt"
  local rc=$?
  [ $rc -ne 0 ] || fail "$* succeeded with a $kb KB file limit"
  [ $rc -lt 124 ] || fail "$* ended by a signal ($rc)"
  grep -q "$(basename "$out")" "$d/err.txt" || fail "$*: message does not name $(basename "$out"): $(cat "$d/err.txt")"
  [ ! -e "$out" ] || fail "$*: left $out under its final name"
  local left
  left=$(find "$d/out" -name '*.tmp.*' | head -1)
  [ -z "$left" ] || fail "$*: left the temporary file $left"
  rm -rf "$d/out"
}

limited 40 "$d/out/t.tum.csv" "$LSHLOC" localize --map "$log" --target "$raw" --out "$d/out/t.tum"
limited 20 "$d/out/m.map" "$LSHLOC" map build "$log" --out "$d/out/m.map"
limited 20 "$d/out/g.pgm" "$LSHLOC" map to-grid "$log" --out "$d/out/g"
limited 8 "$d/out/s.tum" "$LSHLOC" slam --log "$raw" --out "$d/out/s.tum"
limited 30 "$d/out/sim-4-000.log.gz" "$LSHLOC" simulate --out "$d/out" --buildings 1 --seed 4 --scans 600
limited 20 "$d/out/sim-4-000-map.png" "$LSHLOC" localize --map "$log" --target "$raw" --length 50 --plot "$d/out"
echo "full_disk_test: every output refused a full disk cleanly"
