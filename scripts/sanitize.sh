#!/usr/bin/env bash
# CI's sanitizer job (scripts/test.sh runs it after the Release tests): builds
# lshloc with clang, AddressSanitizer and UndefinedBehaviorSanitizer
# (LSHLOC_SANITIZE=address,undefined; any finding aborts the test) in
# build-sanitize/, runs the ctest suite under them, then gives each libFuzzer
# target a smoke run from its seed corpus.
#   scripts/sanitize.sh [--fuzz-time SECONDS] [--thread]
# --fuzz-time: default 20; 0 skips the smoke runs. --thread instead builds the
# unit tests with ThreadSanitizer (build-tsan/) and runs the concurrent ones
# (the live map's threads and several localizers on one map: ctest -R "Live|SharedMap").
# -O1 and a unity build keep build plus tests within CI's budget. Not run here:
# `format` and `layers` (they check source text, no compiled code), the
# Python bindings (the interpreter is not instrumented), `full_disk`
# (file-size limits around commands cli_localize already runs instrumented:
# 30 s of CI) and the few long tests named below; the Release tests run them. (`fleet_loopback` skips itself
# under sanitizers.)
set -euo pipefail
cd "$(dirname "$0")/.."
fuzz_time=20
thread=0
while [ $# -gt 0 ]; do
  case "$1" in
    --fuzz-time) fuzz_time=$2; shift 2 ;;
    --thread) thread=1; shift ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "sanitize.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
start=$(date +%s)
if [ "$thread" = 1 ]; then
  cmake -G Ninja -S . -B build-tsan -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=None \
    -DCMAKE_CXX_FLAGS="-O1 -gline-tables-only" -DCMAKE_UNITY_BUILD=ON -DLSHLOC_SANITIZE=thread >/dev/null
  cmake --build build-tsan -j"$(nproc)" --target lshloc_tests
  TSAN_OPTIONS="halt_on_error=1" ctest --test-dir build-tsan -j"$(nproc)" --output-on-failure -R '^(Live|SharedMap)'
  echo "sanitize: the concurrent tests under ThreadSanitizer passed in $(($(date +%s) - start)) s"
  exit 0
fi
cmake -G Ninja -S . -B build-sanitize -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=None \
  -DCMAKE_CXX_FLAGS="-O1 -gline-tables-only" -DCMAKE_UNITY_BUILD=ON \
  -DLSHLOC_SANITIZE=address,undefined -DLSHLOC_BUILD_FUZZERS=ON >/dev/null
cmake --build build-sanitize -j"$(nproc)"
echo "sanitize: built in $(($(date +%s) - start)) s"
# Left to the Release run as well, for CI's 15 minutes: option parsing (cli_options) and six long runs whose
# code paths shorter tests here take too (policy and equality checks on whole synthetic or real-log runs; the
# live insertion the Live* tests take; bench scale's trace, whose localizer runs everywhere here).
long='Localizer\.(AMapCompleteBeforeTheFirstScan|GivesUpAWellSupportedPlace|APlaceMappedAfterTheTargetSawIt).*|'\
'MapStoreRealData\..*|LshDatabase\.FindsTheExactNearestNeighbourMostOfTheTime|cli_bench_scale'
ctest --test-dir build-sanitize -j"$(nproc)" --output-on-failure -E "^(format|layers|full_disk|cli_options|$long)\$"
echo "sanitize: ctest under ASan and UBSan passed ($(($(date +%s) - start)) s so far)"
if [ "$fuzz_time" != 0 ]; then
  # All targets at once: each smoke run is --fuzz-time seconds of wall time, sharing the cores.
  ./scripts/fuzz.sh --build-dir build-sanitize --time "$fuzz_time" --jobs 8
fi
echo "sanitize: done in $(($(date +%s) - start)) s"
