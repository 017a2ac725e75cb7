#!/usr/bin/env bash
# Checks that every C++ file of the repository is formatted as .clang-format
# says (clang-format from scripts/setup.sh). Lists the files that are not and
# exits 1; `git ls-files '*.cpp' '*.hpp' | xargs clang-format -i` fixes them.
set -uo pipefail
cd "$(dirname "$0")/.."
command -v clang-format >/dev/null || { echo "check_format: clang-format not found (run scripts/setup.sh)"; exit 1; }
n=$(git ls-files '*.cpp' '*.hpp' | wc -l)
# clang-format names each unformatted file in its "file:line:col: error:" lines.
report=$(git ls-files -z '*.cpp' '*.hpp' | xargs -0 -P "$(nproc)" -n 16 clang-format --dry-run --Werror 2>&1)
status=$?
bad=$(grep -oE '^[^:]+:[0-9]+:[0-9]+: error' <<<"$report" | cut -d: -f1 | sort -u)
for f in $bad; do echo "not formatted: $f"; done
count=$(grep -c . <<<"$bad")
echo "check_format: $n files, $count not formatted"
if [ "$status" -ne 0 ] && [ "$count" -eq 0 ]; then echo "check_format: clang-format failed: $report"; exit 1; fi
[ "$count" -eq 0 ] && [ "$status" -eq 0 ]
