#!/usr/bin/env bash
# Checks that every C++ file of the repository is formatted as .clang-format
# says (clang-format from scripts/setup.sh). Lists the files that are not and
# exits 1; `git ls-files '*.cpp' '*.hpp' | xargs clang-format -i` fixes them.
set -uo pipefail
cd "$(dirname "$0")/.."
command -v clang-format >/dev/null || { echo "check_format: clang-format not found (run scripts/setup.sh)"; exit 1; }
bad=0; n=0
while IFS= read -r f; do
  n=$((n + 1))
  clang-format --dry-run --Werror "$f" >/dev/null 2>&1 || { echo "not formatted: $f"; bad=$((bad + 1)); }
done < <(git ls-files '*.cpp' '*.hpp')
echo "check_format: $n files, $bad not formatted"
[ "$bad" -eq 0 ]
