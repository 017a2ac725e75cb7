#!/usr/bin/env bash
# Builds lshloc's libFuzzer targets (clang, ASan + UBSan) in build-fuzz/ and
# runs each from its seed corpus (fuzz/corpus/<name>/, read only: new inputs
# go to a scratch directory), as many at a time as there are cores.
#   scripts/fuzz.sh [--time SECONDS | --runs N] [--build-dir DIR] [--jobs N] [TARGET...]
# Default: 30 s each for every target. --build-dir takes the targets from a
# build already configured with LSHLOC_BUILD_FUZZERS (scripts/sanitize.sh's);
# --jobs: targets run at a time (default: the cores).
# Prints one line per target with its executions; exits non-zero on any
# finding (the crashing input is kept in <build>/findings/). docs/reliability.md
# records the long runs.
set -euo pipefail
cd "$(dirname "$0")/.."
limit=(-max_total_time=30)
build=build-fuzz
jobs_max=$(nproc)
while [ $# -gt 0 ]; do
  case "$1" in
    --time) limit=(-max_total_time="$2"); shift 2 ;;
    --runs) limit=(-runs="$2"); shift 2 ;;
    --build-dir) build=$2; shift 2 ;;
    --jobs) jobs_max=$2; shift 2 ;;
    -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
    *) break ;;
  esac
done
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(carmen_reader pose_table config_json map_loader ros_map map_log_record)
if [ ! -f "$build/CMakeCache.txt" ]; then
  [ "$build" = build-fuzz ] || { echo "fuzz.sh: $build is not a configured build" >&2; exit 2; }
  cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLSHLOC_BUILD_FUZZERS=ON -DLSHLOC_BUILD_TESTS=OFF \
    -DCMAKE_CXX_COMPILER=clang++ >/dev/null
fi
cmake --build "$build" -j"$(nproc)" --target "${targets[@]/%/_fuzz}" >/dev/null
mkdir -p "$build/findings"

# One target: its summary line goes to $build/findings/<target>.result.
fuzz_one() {
  local t=$1 scratch log result runs secs
  scratch=$(mktemp -d)
  log=$build/findings/$t.log
  if "$build/bin/${t}_fuzz" "${limit[@]}" -max_len=16384 -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 \
       -artifact_prefix="$build/findings/$t-" "$scratch" "fuzz/corpus/$t" >"$log" 2>&1; then
    result="no finding"
  else
    result="FINDING (see $log and $build/findings/$t-*)"
  fi
  runs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' || echo "?")
  secs=$(grep -oE 'Done [0-9]+ runs in [0-9]+ second' "$log" | grep -oE 'in [0-9]+' | grep -oE '[0-9]+' || echo "?")
  echo "fuzz $t: $runs executions in ${secs} s, $result" >"$build/findings/$t.result"
  rm -rf "$scratch"
}

for t in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs_max" ]; do wait -n || true; done
  fuzz_one "$t" &
done
wait
status=0
for t in "${targets[@]}"; do
  cat "$build/findings/$t.result"
  grep -q "no finding" "$build/findings/$t.result" || status=1
done
exit $status
