#!/usr/bin/env bash
# `lshloc calibration` on hand-made traces with a known answer: the bins and
# the expected calibration error, the diagram's files, and errors that name
# the file, the line and what was expected.
# Usage: cli_calibration_test.sh LSHLOC
set -euo pipefail
LSHLOC=$1
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
header="scan,timestamp,has_estimate,submap,x,y,theta,localized,confidence,mean_score,scored,margin,truth_x,truth_y,truth_theta,error_m,heading_error_deg"
# Right: within 2 m and 10 deg with an estimate. Values 0.95 (3 right of 4),
# 0.15 (1 right of 2: 11 deg off counts as wrong); a row without truth is skipped.
# As `eval --trace` writes them: no pose without an estimate, no heading error
# for an estimate in another submap (error inf).
cat >"$d/a.csv" <<CSV
$header
0,0.0,1,0,0,0,0,1,0.95,0.5,100,0.3,0,0,0,0.10,1.0
1,0.1,1,0,0,0,0,1,0.95,0.5,100,0.3,0,0,0,0.20,2.0
2,0.2,1,0,0,0,0,1,0.95,0.5,100,0.3,0,0,0,1.90,9.0
3,0.3,1,0,0,0,0,1,0.95,0.5,100,0.3,0,0,0,inf,
4,0.4,1,0,0,0,0,0,0.15,0.5,100,0.3,0,0,0,0.10,11.0
5,0.5,1,0,0,0,0,0,0.15,0.5,100,0.3,,,,,
CSV
mkdir "$d/dir" && cat >"$d/dir/b.csv" <<CSV
$header
0,0.0,0,,,,,0,0.15,0,0,0,0,0,0,inf,
1,0.1,1,0,0,0,0,0,0.15,0.5,100,0.3,0,0,0,0.5,3.0
CSV
echo "not a trace" >"$d/dir/b.csv.truth.csv"
# Traces with interpolated truth: there a heading is wrong only beyond 45 deg
# (12 deg off is right, 50 deg wrong); a row estimated in another submap is
# judged (wrong) without any truth.
cat >"$d/c.csv" <<CSV
$header,interpolated_x,interpolated_y,interpolated_theta,judged_error_m,judged_heading_error_deg
0,0.0,1,0,0,0,0,1,0.95,0.5,100,0.3,,,,,,0,0,0,0.10,12.0
1,0.1,1,0,0,0,0,1,0.95,0.5,100,0.3,,,,,,0,0,0,0.10,50.0
2,0.2,1,1,0,0,0,1,0.95,0.5,100,0.3,,,,,,,,,inf,
3,0.3,1,0,0,0,0,1,0.95,0.5,100,0.3,,,,,,,,,,
CSV
"$LSHLOC" calibration "$d/c.csv" >"$d/jc.json"
python3 - "$d/jc.json" <<'PY' || fail "calibration with interpolated truth: $(cat "$d/jc.json")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["scans"] == 3 and j["right"] == 1, j
PY
"$LSHLOC" calibration "$d/a.csv" "$d/dir" --out "$d/rel" >"$d/j.json"
python3 - "$d/j.json" "$d/rel.csv" <<'PY' || fail "calibration numbers: $(cat "$d/j.json")"
import csv, json, sys
j = json.load(open(sys.argv[1]))
assert j["traces"] == 2 and j["scans"] == 7 and j["right"] == 4, j
b = j["bins"]
assert b[9]["count"] == 4 and abs(b[9]["share_right"] - 0.75) < 1e-12, b[9]
assert b[1]["count"] == 3 and abs(b[1]["share_right"] - 1 / 3) < 1e-12, b[1]
ece = 4 / 7 * abs(0.95 - 0.75) + 3 / 7 * abs(0.15 - 1 / 3)
assert abs(j["expected_calibration_error"] - ece) < 1e-9, (j["expected_calibration_error"], ece)
rows = list(csv.DictReader(open(sys.argv[2])))
assert len(rows) == 10 and int(rows[9]["count"]) == 4
PY
[ "$(head -c 4 "$d/rel.png" | tail -c 3)" = PNG ] || fail "no PNG diagram"
grep -q "<svg" "$d/rel.svg" || fail "no SVG diagram"

# A trace `eval --trace` wrote (real logs; skipped without them): a scan without
# an estimate has no pose, one in another submap no heading error, and
# calibration reads it.
data=${LSHLOC_DATA:-$(dirname "$0")/../../shared/data}
if [ -d "$data/intel" ]; then
  "$LSHLOC" eval --building intel --start 5004 --length 30 --submaps 1 --trace "$d/tr.csv" >/dev/null 2>&1 ||
    fail "eval --trace"
  python3 - "$d/tr.csv" <<'PY' || fail "eval --trace rows"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
none = [r for r in rows if r["submap"] == ""]
assert none and all(r["x"] == r["submap_id"] == r["heading_deg"] == "" for r in none), none[:1]
assert all(r["heading_error_deg"] == "" for r in rows if r["error_m"] == "inf")
assert all(r["heading_error_deg"] != "" for r in rows if r["error_m"] not in ("", "inf"))
# Every scan between two truth scans is judged: measured truth or interpolated, never both; error_m stays at
# the measured truth scans (as before), judged_error_m covers every judged scan.
assert all(not (r["truth_x"] and r["interpolated_x"]) for r in rows)
judged = [r for r in rows if r["truth_x"] or r["interpolated_x"]]
assert len([r for r in rows if r["interpolated_x"]]) > len([r for r in rows if r["truth_x"]]), "no interpolated truth"
assert all(r["judged_error_m"] != "" for r in judged)
assert all((r["error_m"] != "") == (r["truth_x"] != "") for r in rows)
assert all(r["error_m"] == r["judged_error_m"] for r in rows if r["truth_x"])
PY
  "$LSHLOC" calibration "$d/tr.csv" >/dev/null || fail "calibration of an eval trace"
  # A guard that leaves the target's own submap empty is warned.
  "$LSHLOC" eval --building intel --start 5004 --length 30 --submaps 1 --guard 1e7 >/dev/null 2>"$d/guard.err" ||
    fail "eval with a long guard"
  grep -q "warning: intel has no map scans outside the window" "$d/guard.err" || fail "guard: $(cat "$d/guard.err")"
else
  echo "cli_calibration: no real logs at $data: the eval --trace check is skipped"
fi

# Bad input: a missing column, a value outside [0, 1], a short row.
echo "scan,confidence" >"$d/bad1.csv"
if "$LSHLOC" calibration "$d/bad1.csv" 2>"$d/e1"; then fail "a trace without error_m was accepted"; fi
grep -q "bad1.csv:1: no column \"submap\"" "$d/e1" || fail "missing column message: $(cat "$d/e1")"
{ echo "$header"; echo "0,0.0,1,0,0,0,0,1,1.5,0.5,100,0.3,0,0,0,0.1,1.0"; } >"$d/bad2.csv"
if "$LSHLOC" calibration "$d/bad2.csv" 2>"$d/e2"; then fail "a value of 1.5 was accepted"; fi
grep -q "bad2.csv:2: confidence 1.5 is outside \[0, 1\]" "$d/e2" || fail "range message: $(cat "$d/e2")"
{ echo "$header"; echo "0,0.0,1"; } >"$d/bad3.csv"
if "$LSHLOC" calibration "$d/bad3.csv" 2>"$d/e3"; then fail "a short row was accepted"; fi
grep -q "bad3.csv:2: 3 fields; expected 17" "$d/e3" || fail "short row message: $(cat "$d/e3")"
echo "cli_calibration: ok"
