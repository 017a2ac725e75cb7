#!/usr/bin/env bash
# Crash test of the map store (docs/map-format.md, "Durability").
#
# A child process appends a stream of mapper scans (a corrected log) to a
# saved map with `lshloc map append --ack-lines`, which prints how many of
# the stream's scans are acknowledged (fsync'ed) after each batch. The child
# is killed with SIGKILL at KILLS random moments; each time the next child
# resumes where the map stands. After every kill:
#   - `lshloc map verify` passes on the map as the crash left it;
#   - every acknowledged scan is in the map, and nothing else is: the stream's
#     submap holds a prefix of the stream, at least the acknowledged scans
#     and at most one unfinished fsync batch more, and no other submap grew;
#   - a map rebuilt without crashes from the same scans (a copy of the base
#     map, the stream appended uninterrupted up to that count) localizes a
#     target window identically (trajectory files compared byte for byte).
# Then the map is compacted (`lshloc map compact`), so that each child starts
# from a fresh snapshot and compaction is checked at every step too.
# Prints a line per kill and a summary line; exits 0 only when every kill passed.
#
# Environment: LSHLOC (binary, default build/bin/lshloc), LSHLOC_DATA (data
# directory, default ../shared/data), KILLS (20), SEED (1), SYNC_EVERY (4),
# MAX_DELAY_MS (600; each kill comes 0..MAX_DELAY_MS ms after the child's
# first acknowledgement, so that it lands while scans stream in, not while the
# child is still loading the map).
set -euo pipefail
cd "$(dirname "$0")/.."
LSHLOC=${LSHLOC:-build/bin/lshloc}
DATA=${LSHLOC_DATA:-../shared/data}
KILLS=${KILLS:-20}
SEED=${SEED:-1}
SYNC_EVERY=${SYNC_EVERY:-4}
MAX_DELAY_MS=${MAX_DELAY_MS:-600}
BASE_LOG=$DATA/intel/intel.gfs.log.gz
STREAM_LOG=$DATA/fr079/fr079-complete.gfs.log.gz
TARGET_LOG=$DATA/fr079/fr079.recon-from-bag.log.gz
for f in "$BASE_LOG" "$STREAM_LOG" "$TARGET_LOG"; do
  [ -f "$f" ] || { echo "crash test: $f is missing (set LSHLOC_DATA)"; exit 2; }
done
[ -x "$LSHLOC" ] || { echo "crash test: $LSHLOC is not an executable (set LSHLOC)"; exit 2; }

work=$(mktemp -d)
child=""
cleanup() { [ -n "$child" ] && kill -9 "$child" 2>/dev/null; rm -rf "$work"; }
trap cleanup EXIT
RANDOM=$SEED

json_get() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))$2)" "$1"; }
# Scans of submap NAME in map MAP (0 when it has none).
submap_scans() {
  "$LSHLOC" map info "$1" --json >"$work/info.json"
  python3 -c "
import json, sys
j = json.load(open(sys.argv[1]))
print(sum(s['scans'] for s in j['submap_list'] if s['name'] == sys.argv[2]))" "$work/info.json" "$2"
}

"$LSHLOC" map build --out "$work/base.map" --name base "$BASE_LOG" >/dev/null 2>&1
stream_len=$("$LSHLOC" map build --out "$work/stream-only.map" --json "$STREAM_LOG" 2>/dev/null |
  python3 -c "import json,sys; print(json.load(sys.stdin)['scans'])")
base_scans=$(submap_scans "$work/base.map" base)
cp "$work/base.map" "$work/map.map"
cp "$work/base.map" "$work/finished.map"  # base and the finished streams, compacted
echo "crash test: base map $base_scans scans; stream $(basename "$STREAM_LOG"), $stream_len scans, fsync every $SYNC_EVERY; $KILLS kills"

passed=0 lost=0 unreadable=0 extra=0 different=0 torn_count=0
stream=1      # streams fill submaps stream-1, stream-2, ... in turn
done_scans=0  # scans of finished streams
for kill_no in $(seq 1 "$KILLS"); do
  name="stream-$stream"
  before=$(submap_scans "$work/map.map" "$name")
  delay_ms=$((RANDOM % (MAX_DELAY_MS + 1)))
  "$LSHLOC" map append "$work/map.map" "$STREAM_LOG" --submap "$name" --from "$before" \
    --sync-every "$SYNC_EVERY" --ack-lines >"$work/acks.txt" 2>"$work/append.err" &
  child=$!
  for _ in $(seq 1 600); do  # up to 60 s for the map to load and the first batch to be acknowledged
    if [ -s "$work/acks.txt" ] || ! kill -0 "$child" 2>/dev/null; then break; fi
    sleep 0.1
  done
  sleep "$(printf '%d.%03d' $((delay_ms / 1000)) $((delay_ms % 1000)))"
  kill -9 "$child" 2>/dev/null || true
  wait "$child" 2>/dev/null || true
  child=""
  acked=$(awk '/^acknowledged /{n=$2} END{print n+0}' "$work/acks.txt")
  [ "$acked" -ge "$before" ] || acked=$before
  problems=""
  torn=""
  if ! "$LSHLOC" map verify "$work/map.map" >"$work/verify.out" 2>&1; then
    unreadable=$((unreadable + 1)); problems+=" unreadable: $(tail -c 200 "$work/verify.out")"
  elif grep -q "is torn" "$work/verify.out"; then
    torn=" (a torn last record, dropped)"; torn_count=$((torn_count + 1))
  fi
  present=$(submap_scans "$work/map.map" "$name" 2>/dev/null || echo -1)
  total=$(json_get "$work/info.json" "['scans']" 2>/dev/null || echo -1)
  if [ "$present" -lt "$acked" ]; then
    lost=$((lost + acked - present)); problems+=" lost $((acked - present)) acknowledged scans"
  fi
  if [ "$present" -gt $((acked + SYNC_EVERY)) ] || [ "$total" -ne $((base_scans + done_scans + present)) ]; then
    extra=$((extra + 1)); problems+=" extra scans (submap $present, map $total, acknowledged $acked)"
  fi
  # The same scans without crashes: base, finished streams, this stream's prefix.
  cp "$work/finished.map" "$work/rebuilt.map"
  if [ "$present" -gt 0 ]; then
    "$LSHLOC" map append "$work/rebuilt.map" "$STREAM_LOG" --submap "$name" --count "$present" --sync-every 64 \
      >/dev/null 2>&1
  fi
  for m in map rebuilt; do
    "$LSHLOC" localize --map "$work/$m.map" --target "$TARGET_LOG" --start 2000 --length 15 \
      --out "$work/$m.tum" --json >"$work/$m.json" 2>/dev/null || true
  done
  if ! cmp -s "$work/map.tum" "$work/rebuilt.tum" || ! cmp -s "$work/map.tum.csv" "$work/rebuilt.tum.csv" ||
     [ ! -s "$work/map.tum.csv" ]; then
    different=$((different + 1)); problems+=" localizes differently from the rebuilt map"
  fi
  if ! "$LSHLOC" map compact "$work/map.map" >"$work/compact.out" 2>&1 ||
     [ "$(submap_scans "$work/map.map" "$name")" != "$present" ]; then
    problems+=" compaction failed: $(tail -c 200 "$work/compact.out")"
  fi
  if [ -z "$problems" ]; then
    passed=$((passed + 1)); verdict=ok
  else
    verdict="FAIL:$problems"
  fi
  echo "kill $kill_no ${delay_ms} ms after the first acknowledgement: $name had $before, acknowledged $acked, holds $present$torn; $verdict"
  if [ "$present" -ge "$stream_len" ]; then  # this stream is complete: the next kill appends a new one
    done_scans=$((done_scans + present)); stream=$((stream + 1))
    cp "$work/rebuilt.map" "$work/finished.map"
    "$LSHLOC" map compact "$work/finished.map" >/dev/null
  fi
done
echo "crash test: $passed/$KILLS kills passed; $lost acknowledged scans lost, $unreadable unreadable maps, $extra with extra scans, $different localizing differently ($torn_count left a torn record)"
[ "$passed" -eq "$KILLS" ]
