#!/usr/bin/env bash
# `lshloc judge` on a hand-made run with a known answer: a simulated robot's
# true poses as its estimates, judged against every 10th truth pose (the rest
# interpolated along its odometry), with some rows made wrong on purpose;
# then errors that name the file, the line and what was expected.
# Usage: cli_judge_test.sh LSHLOC
set -euo pipefail
LSHLOC=$1
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
"$LSHLOC" simulate --out "$d/sim" --buildings 1 --seed 4 >/dev/null 2>&1 || fail "simulate"
b=$(ls "$d/sim")
log="$d/sim/$b/$b.log.gz"
poses=$(ls "$d/sim/$b/"*poses*.txt)
# Rows 100..299 of the log: the truth itself, confident; every 10th truth pose kept for the judge.
python3 - "$poses" "$d" "$b" <<'PY'
import math, sys
poses, d, b = sys.argv[1], sys.argv[2], sys.argv[3]
truth = [l.split() for l in open(poses) if l.strip() and not l.startswith("#")]
open(f"{d}/thinned.txt", "w").writelines(" ".join(t) + "\n" for k, t in enumerate(truth) if k % 10 == 0)
def rows(change):
    out = ["scan,log_scan,time,submap,submap_id,x,y,heading_deg,confident\n"]
    for k in range(100, 300):
        t, x, y, th = truth[k][0], float(truth[k][1]), float(truth[k][2]), math.degrees(float(truth[k][3]))
        sub, conf = b, 1
        if k in change: sub, x, y, th = change[k](sub, x, y, th)
        out.append(f'{k - 100},{k},{t},"{sub}",0,{x:.4f},{y:.4f},{th:.3f},{conf}\n')
    return out
open(f"{d}/right.csv", "w").writelines(rows({}))
open(f"{d}/wrong.csv", "w").writelines(rows({
    150: lambda s, x, y, th: (s, x + 3.0, y, th),             # 3 m off: wrong
    151: lambda s, x, y, th: ("other, building", x, y, th),   # another submap (a name with a comma): wrong
    152: lambda s, x, y, th: (s, x, y, th + 30.0),            # 30 deg off an interpolated truth: not wrong
    160: lambda s, x, y, th: (s, x, y, th + 30.0),            # 30 deg off a measured truth: wrong
    161: lambda s, x, y, th: (s, x, y, th + 60.0),            # 60 deg off an interpolated truth: wrong
}))
PY
"$LSHLOC" judge "$d/right.csv" --log "$log" --truth "$d/thinned.txt" --submap "$b" --json >"$d/right.json" ||
  fail "judge: $(cat "$d/right.json")"
"$LSHLOC" judge "$d/wrong.csv" --log "$log" --truth "$d/thinned.txt" --submap "$b" --json >"$d/wrong.json" ||
  fail "judge of the wrong run"
python3 - "$d/right.json" "$d/wrong.json" <<'PY' || fail "judge numbers: $(cat "$d/right.json" "$d/wrong.json")"
import json, sys
r, w = (json.load(open(p)) for p in sys.argv[1:3])
# Truth at rows 0, 10, ..., 190 (log scans 100..290): judged from the first to the last, 191 scans.
assert r["scans"] == 200 and r["truth_scans"] == 20 and r["judged_scans"] == 191, r
assert r["confident_scans"] == 200 and r["confident_judged"] == 191 and r["confident_wrong"] == 0, r
assert r["success"] and r["final_error_m"] < 0.05, r
# Rows 50 and 60 (log scans 150 and 160) have a measured truth, 51 is in another submap, 61 is turned
# 60 deg off an interpolated truth: wrong; 52, turned 30 deg off an interpolated truth, is not.
assert w["confident_wrong_scans"] == [50, 51, 60, 61], w
assert w["confident_wrong_at_truth"] == 2 and w["longest_confident_wrong_run"] == 2, w
PY
"$LSHLOC" judge "$d/wrong.csv" --log "$log" --truth "$d/thinned.txt" --submap "$b" | grep -q "4 wrong" ||
  fail "judge's words"

# Bad input: a CSV without the columns, the wrong log, an unclosed quote.
echo "scan,confidence" >"$d/bad1.csv"
if "$LSHLOC" judge "$d/bad1.csv" --log "$log" --truth "$d/thinned.txt" --submap "$b" 2>"$d/e1"; then
  fail "a CSV without log_scan was accepted"
fi
grep -q "bad1.csv:1: no column \"log_scan\"" "$d/e1" || fail "missing column message: $(cat "$d/e1")"
sed '3s/,1$/,1/; 3s/^\([0-9]*\),\([0-9]*\),\([0-9.]*\)/\1,\2,9\3/' "$d/right.csv" >"$d/bad2.csv"
if "$LSHLOC" judge "$d/bad2.csv" --log "$log" --truth "$d/thinned.txt" --submap "$b" 2>"$d/e2"; then
  fail "a row whose time is not its scan's was accepted"
fi
grep -q "bad2.csv: row 3 has time .* is it the run's log?" "$d/e2" || fail "wrong-log message: $(cat "$d/e2")"
{ head -1 "$d/right.csv"; echo '0,100,1000.0,"open,0,1,2,3,1'; } >"$d/bad3.csv"
if "$LSHLOC" judge "$d/bad3.csv" --log "$log" --truth "$d/thinned.txt" --submap "$b" 2>"$d/e3"; then
  fail "an unclosed quote was accepted"
fi
grep -q "bad3.csv:2: a quoted CSV field is not closed" "$d/e3" || fail "quote message: $(cat "$d/e3")"
echo "cli_judge: ok"
