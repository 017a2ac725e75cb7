#!/usr/bin/env bash
# Installs dependencies, builds lshloc (Release) and runs the whole test suite.
# Tests that need the real logs skip when ../shared/data is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)"
ctest --test-dir build -j"$(nproc)" --output-on-failure
