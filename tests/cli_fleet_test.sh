#!/usr/bin/env bash
# A fleet on loopback, as a user runs it: the test's own redis-server on a
# free port, two `lshloc mapper` processes publishing simulated buildings,
# then `lshloc localize --map redis://...` must answer as the same logs given
# as --map files, in the same order: the same trajectory, byte for byte (the
# reader hands each poll's updates out round robin, as files are fed); and a
# localizer started while a mapper is still publishing follows the map and
# localizes; a mapper on a server that refuses writes gives up, naming why.
# Skips when redis-server is absent.
# Usage: cli_fleet_test.sh LSHLOC
set -euo pipefail
LSHLOC=$1
command -v redis-server >/dev/null || { echo "cli_fleet_test: redis-server not found (scripts/setup.sh installs it): skipped"; exit 0; }
d=$(mktemp -d)
port=$(python3 -c "import socket; s=socket.socket(); s.bind(('127.0.0.1', 0)); print(s.getsockname()[1]); s.close()")
redis-server --port "$port" --bind 127.0.0.1 --save "" --appendonly no --dir "$d" --logfile redis.log &
server=$!
trap 'kill $server 2>/dev/null || true; wait $server 2>/dev/null || true; rm -rf "$d"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
url=redis://127.0.0.1:$port
for _ in $(seq 50); do redis-cli -p "$port" ping >/dev/null 2>&1 && break; sleep 0.1; done

"$LSHLOC" simulate --out "$d/sim" --buildings 2 --seed 3 --scans 600 >/dev/null
a=$d/sim/sim-3-000/sim-3-000-corrected.log.gz b=$d/sim/sim-3-001/sim-3-001-corrected.log.gz
target=(--target "$d/sim/sim-3-001/sim-3-001.log.gz" --start 300 --length 150 --json)

"$LSHLOC" mapper --redis "$url" "$a" >"$d/ma.json" 2>/dev/null
"$LSHLOC" mapper --redis "$url" "$b" >"$d/mb.json" 2>/dev/null
"$LSHLOC" localize --map "$url" "${target[@]}" --out "$d/fleet.tum" >"$d/fleet.json"
"$LSHLOC" localize --map "$a" --map "$b" "${target[@]}" --out "$d/files.tum" >"$d/files.json" 2>/dev/null
cmp "$d/fleet.tum" "$d/files.tum" || fail "the fleet's map gives another trajectory than the files"
python3 - "$d/ma.json" "$d/fleet.json" "$d/files.json" <<'PY' || fail "the fleet's map answers otherwise than the files"
import json, sys
m = json.load(open(sys.argv[1]))
assert m["scans"] == 600 and m["first_seq"] == 0 and m["next_seq"] == 600, m
f, g = json.load(open(sys.argv[2])), json.load(open(sys.argv[3]))
assert f["map_log"]["history_updates"] == 1200 and f["map_log"]["duplicates"] == 0, f["map_log"]
for k in ("localized", "final_submap", "map_features", "final_pose"):
    assert f[k] == g[k], (k, f[k], g[k])
assert f["localized"] and f["final_submap"] == "sim-3-001-corrected.log.gz"
PY

# A mapper restarted on its submap continues its sequence numbers.
"$LSHLOC" mapper --redis "$url" --submap sim-3-000-corrected.log.gz "$a" >"$d/ma2.json" 2>/dev/null
python3 -c "import json,sys; m=json.load(open(sys.argv[1])); assert m['first_seq']==600 and m['next_seq']==1200, m" \
  "$d/ma2.json" || fail "a restarted mapper did not resume its sequence"

# Live: building b is published at 2000 scans/s while the localizer starts and localizes.
"$LSHLOC" mapper --redis "$url?prefix=live" "$a" >/dev/null 2>&1
"$LSHLOC" mapper --redis "$url?prefix=live" --rate 2000 "$b" >/dev/null 2>&1 &
mapper=$!
sleep 0.1
"$LSHLOC" localize --map "$url?prefix=live" "${target[@]}" >"$d/live.json"
wait $mapper
python3 - "$d/live.json" "$d/files.json" <<'PY' || fail "the localizer on a map still being published did not localize"
import json, math, sys
j, g = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
# Every scan arrives, in the catch-up or live (how many live depends on the machine's speed:
# LiveFleet in tests/fleet_test.cpp checks live application deterministically).
assert j["map_log"]["history_updates"] + j["map_log"]["live_updates"] <= 1200, j["map_log"]
# It was confident at some scan (how late depends on the machine's speed too) and ends at the
# place the finished map gives.
assert j["first_localized_at"] is not None and j["final_submap"] == "sim-3-001-corrected.log.gz", j
(x, y, t), (u, v, w) = j["final_pose"], g["final_pose"]
assert math.hypot(x - u, y - v) < 0.5 and abs(math.remainder(t - w, 2 * math.pi)) < math.radians(5), (j, g)
PY

# A server that lost a stream (restarted without its data) while a restarted mapper publishes:
# the mapper says so instead of reporting its scans as published.
"$LSHLOC" mapper --redis "$url?prefix=lost" "$a" >/dev/null 2>&1
"$LSHLOC" mapper --redis "$url?prefix=lost" --rate 20 --retry 5 "$a" >"$d/lost.json" 2>"$d/lost.err" &
mapper=$!
sleep 1
# (at once: a scan published between the two would start the stream anew at its own number)
printf 'MULTI\nDEL lost:{sim-3-000-corrected.log.gz}:log\nCLIENT KILL TYPE normal SKIPME yes\nEXEC\n' |
  redis-cli -p "$port" >/dev/null
rc=0
wait $mapper || rc=$?
[ "$rc" != 0 ] || fail "a mapper whose stream the server lost exited 0: $(cat "$d/lost.json")"
grep -q "lost updates it had acknowledged" "$d/lost.err" || fail "lost stream: $(tail -3 "$d/lost.err")"

# A server that answers but takes no writes (out of memory): the mapper gives up after --retry
# seconds without progress, naming the server's reason, instead of reconnecting forever.
"$LSHLOC" mapper --redis "$url?prefix=full" --rate 50 --retry 2 "$a" >/dev/null 2>"$d/full.err" &
mapper=$!
sleep 1
redis-cli -p "$port" config set maxmemory 1 >/dev/null
rc=0
timeout 30 tail --pid=$mapper -f /dev/null || fail "a mapper on a server refusing writes is still running after 30 s"
wait $mapper || rc=$?
redis-cli -p "$port" config set maxmemory 0 >/dev/null
[ "$rc" != 0 ] || fail "a mapper on a server refusing writes exited 0"
grep -q "OOM" "$d/full.err" && grep -q "gave up" "$d/full.err" || fail "refused writes: $(tail -3 "$d/full.err")"

# A live map lost while a stream localizes (the server stops mid-stream): said, and exit 1, not 0.
zcat "$d/sim/sim-3-001/sim-3-001.log.gz" >"$d/stream.log"
sed -n 1,300p "$d/stream.log" >"$d/part1.log"
sed -n 301,400p "$d/stream.log" >"$d/part2.log"
{ cat "$d/part1.log"; sleep 6; cat "$d/part2.log"; } | "$LSHLOC" localize --map "$url" --target - >"$d/lost.out" \
  2>"$d/lost.err" &
streamer=$!
# The server stops once the stream's rows come out (the localizer follows the map), within 20 s.
for _ in $(seq 200); do [ -s "$d/lost.out" ] && break; sleep 0.1; done
kill $server; wait $server 2>/dev/null || true
rc=0; wait $streamer || rc=$?
[ "$rc" = 1 ] || fail "a stream whose live map was lost exited $rc: $(tail -2 "$d/lost.err")"
grep -q "$url" "$d/lost.err" || fail "lost map message: $(tail -2 "$d/lost.err")"

# A wrong address names it.
if "$LSHLOC" localize --map redis://127.0.0.1:1 "${target[@]}" >/dev/null 2>"$d/err"; then fail "a dead server was accepted"; fi
grep -q "redis://127.0.0.1:1: cannot connect" "$d/err" || fail "dead server message: $(cat "$d/err")"
echo "cli_fleet_test: passed"
