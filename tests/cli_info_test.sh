#!/usr/bin/env bash
# `lshloc info --buildings`: the data directory's fifteen buildings, one JSON
# line each; the five with ground truth have a raw log, a corrected log and
# poses on disk, and the tool reads a log the catalog names; a missing data
# directory is named in the error. Skips when the shared data is absent.
# Usage: cli_info_test.sh LSHLOC DATA_DIR
set -euo pipefail
LSHLOC=$1
data=${LSHLOC_DATA:-$2}
fail() { echo "FAIL: $*"; exit 1; }
if "$LSHLOC" --data /nonexistent/lshloc-data info --buildings 2>"${TMPDIR:-/tmp}/cli_info_err.$$"; then
  fail "a missing data directory was accepted"
fi
grep -q "/nonexistent/lshloc-data" "${TMPDIR:-/tmp}/cli_info_err.$$" || fail "the error does not name the directory"
rm -f "${TMPDIR:-/tmp}/cli_info_err.$$"
# A data directory that holds none of the logs: listed, with a warning saying so.
empty=$(mktemp -d)
"$LSHLOC" --data "$empty" info --buildings >/dev/null 2>"$empty/err" || fail "an empty data directory"
grep -q "warning: .*holds none of the buildings' logs" "$empty/err" || fail "no warning: $(cat "$empty/err")"
rm -rf "$empty"
# An answer lost on its way out is no success (a full disk: /dev/full).
if [ -w /dev/full ]; then
  err=$(mktemp)
  if "$LSHLOC" localize --print-config >/dev/full 2>"$err"; then fail "a lost stdout exited 0"; fi
  grep -q "writing to standard output: No space left on device" "$err" || fail "stdout error: $(cat "$err")"
  rm -f "$err"
fi
if "$LSHLOC" info --buildings some.log 2>/dev/null; then fail "--buildings with a LOG was accepted"; fi
if [ ! -d "$data" ]; then echo "shared data directory $data not found: skipped"; exit 0; fi
"$LSHLOC" --data "$data" info --buildings | python3 -c '
import json, os, subprocess, sys
rows = [json.loads(l) for l in sys.stdin]
assert len(rows) == 15, f"{len(rows)} buildings, expected 15"
by = {r["building"]: r for r in rows}
for b in ("fr079", "fr101", "intel", "aces", "mit-csail"):
    for field in ("raw_log", "corrected_log", "poses"):
        assert by[b][field] and os.path.isfile(by[b][field]), f"{b} {field}: {by[b][field]}"
assert by["fr101"]["relations"] is None, "fr101 has no relations file"
assert by["acapulco"]["raw_log"] is None and by["acapulco"]["corrected_log"], by["acapulco"]
out = subprocess.run([sys.argv[1], "info", by["intel"]["corrected_log"]], capture_output=True, text=True, check=True)
assert json.loads(out.stdout)["scans"] > 100, out.stdout
' "$LSHLOC" || fail "the building list"
echo "cli_info: ok"
