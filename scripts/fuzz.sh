#!/usr/bin/env bash
# Builds lshloc's libFuzzer targets (clang, ASan + UBSan) in build-fuzz/ and
# runs each from its seed corpus (fuzz/corpus/<name>/, read only: new inputs
# go to a scratch directory).
#   scripts/fuzz.sh [--time SECONDS | --runs N] [TARGET...]
# Default: 30 s each for every target. Prints one line per target with its
# executions; exits non-zero on any finding (the crashing input is kept in
# build-fuzz/findings/). docs/reliability.md records the long runs.
set -euo pipefail
cd "$(dirname "$0")/.."
limit=(-max_total_time=30)
while [ $# -gt 0 ]; do
  case "$1" in
    --time) limit=(-max_total_time="$2"); shift 2 ;;
    --runs) limit=(-runs="$2"); shift 2 ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) break ;;
  esac
done
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(carmen_reader pose_table config_json map_loader)
if [ ! -f build-fuzz/CMakeCache.txt ]; then
  cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLSHLOC_BUILD_FUZZERS=ON -DLSHLOC_BUILD_TESTS=OFF \
    -DCMAKE_CXX_COMPILER=clang++ >/dev/null
fi
cmake --build build-fuzz -j"$(nproc)" --target "${targets[@]/%/_fuzz}" >/dev/null
mkdir -p build-fuzz/findings
status=0
for t in "${targets[@]}"; do
  scratch=$(mktemp -d)
  log=build-fuzz/findings/$t.log
  if build-fuzz/bin/${t}_fuzz "${limit[@]}" -max_len=16384 -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 \
       -artifact_prefix=build-fuzz/findings/$t- "$scratch" "fuzz/corpus/$t" >"$log" 2>&1; then
    result="no finding"
  else
    result="FINDING (see $log and build-fuzz/findings/$t-*)"; status=1
  fi
  runs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' || echo "?")
  secs=$(grep -oE 'Done [0-9]+ runs in [0-9]+ second' "$log" | grep -oE 'in [0-9]+' | grep -oE '[0-9]+' || echo "?")
  echo "fuzz $t: $runs executions in ${secs} s, $result"
  rm -rf "$scratch"
done
exit $status
