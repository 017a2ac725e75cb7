#!/usr/bin/env bash
# `lshloc bench scale --trace` on a small synthetic map: each target's trace
# and .truth.csv are written, one row per target scan, and the trace's own
# errors give back the localized-at and final error the JSON line reports.
# Usage: cli_bench_scale_test.sh LSHLOC
set -euo pipefail
LSHLOC=$1
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
"$LSHLOC" bench scale --submaps 3 --targets 2 --map-scans 2000 --target-scans 60 --recall-queries 0 \
  --trace "$d/traces" >"$d/rows.json" 2>"$d/err.txt" || { cat "$d/err.txt"; fail "bench scale --trace failed"; }
python3 - "$d/rows.json" "$d/traces" <<'PY' || fail "traces disagree with the JSON line"
import csv, json, math, os, sys
row = json.loads(open(sys.argv[1]).read().splitlines()[-1])
assert row["submaps"] == 3 and row["targets"] == 2, row
# The check below means something only where targets localize.
assert row["targets_localized"] >= 1, row
for key, runs in (("database", row["per_target"]), ("random", row["random_per_target"])):
    assert len(runs) == 2, runs
    for t in runs:
        path = os.path.join(sys.argv[2], f"{t['building']}.3.{key}.csv")
        rows = list(csv.DictReader(open(path)))
        assert len(rows) == 60, (path, len(rows))
        truth = list(csv.DictReader(open(path + ".truth.csv")))
        assert len(truth) == sum(1 for r in rows if r["error_m"] != ""), path
        scans = [(int(r["scan"]), float(r["error_m"])) for r in rows if r["error_m"] != ""]
        # localized_at: the first truth scan after the last one off by 1 m or more.
        bad = [k for k, (_, e) in enumerate(scans) if not e < 1.0]
        final = scans[-1][1]
        assert t["success"] == (final < 1.0), (path, t)
        if t["success"]:
            assert scans[bad[-1] + 1 if bad else 0][0] == t["localized_at"], (path, t)
            assert math.isclose(final, t["final_error_m"], abs_tol=1e-4), (path, final, t)
PY
# Tracing changes no estimate: the same run without --trace reports the same targets.
"$LSHLOC" bench scale --submaps 3 --targets 2 --map-scans 2000 --target-scans 60 --recall-queries 0 \
  >"$d/plain.json" 2>/dev/null || fail "bench scale without --trace failed"
python3 - "$d/rows.json" "$d/plain.json" <<'PY' || fail "--trace changed the estimates"
import json, sys
a, b = (json.loads(open(p).read().splitlines()[-1]) for p in sys.argv[1:3])
for key in ("per_target", "random_per_target", "targets_localized", "median_localized_at"):
    assert a[key] == b[key], (key, a[key], b[key])
PY
# A trace directory that cannot be made is refused before any map is built.
touch "$d/file"
if "$LSHLOC" bench scale --submaps 1 --targets 1 --trace "$d/file/sub" >/dev/null 2>"$d/err2.txt"; then
  fail "a trace directory under a file was accepted"
fi
grep -q "file/sub" "$d/err2.txt" || { cat "$d/err2.txt"; fail "the error does not name the directory"; }
echo "cli_bench_scale: ok"
