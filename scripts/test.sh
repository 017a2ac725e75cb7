#!/usr/bin/env bash
# Installs dependencies, builds lshloc (Release, a unity build: CI time) with its Python bindings and ROS node,
# runs the whole test suite (the layer check and pytest included), then installs into a temporary prefix and builds
# and runs examples/embed against it (find_package(lshloc)); last, the sanitizer job
# (scripts/sanitize.sh: the ctest suite under ASan and UBSan, and a 20 s smoke run of each fuzz target).
# `scripts/sanitize.sh --thread` (the concurrent tests under ThreadSanitizer) stays outside: CI's 15 minutes.
# Tests that need the real logs skip when ../shared/data is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DLSHLOC_BUILD_PYTHON=ON -DLSHLOC_BUILD_ROS=ON -DCMAKE_UNITY_BUILD=ON >/dev/null
cmake --build build -j"$(nproc)"
ctest --test-dir build -j"$(nproc)" --output-on-failure
prefix=$(mktemp -d)
trap 'rm -rf "$prefix"' EXIT
cmake --install build --prefix "$prefix/install" >/dev/null
cmake -S examples/embed -B "$prefix/embed" -DCMAKE_PREFIX_PATH="$prefix/install" >/dev/null
cmake --build "$prefix/embed" -j"$(nproc)" >/dev/null
"$prefix/embed/embed"
echo "embed: built against the installed package and ran"
# lshloc::core alone needs Eigen alone: the other packages are hidden from the consumer.
cmake -S examples/embed_core -B "$prefix/embed_core" -DCMAKE_PREFIX_PATH="$prefix/install" \
  -DCMAKE_DISABLE_FIND_PACKAGE_PkgConfig=ON -DCMAKE_DISABLE_FIND_PACKAGE_PNG=ON -DCMAKE_DISABLE_FIND_PACKAGE_ZLIB=ON \
  -DCMAKE_DISABLE_FIND_PACKAGE_nlohmann_json=ON -DCMAKE_DISABLE_FIND_PACKAGE_CLI11=ON >/dev/null
cmake --build "$prefix/embed_core" >/dev/null
"$prefix/embed_core/embed_core"
echo "embed_core: lshloc::core built with Eigen alone and localized"
"$prefix/install/bin/lshloc-rosbag-to-carmen" --help >/dev/null
echo "lshloc-rosbag-to-carmen: installed and runs"
./scripts/sanitize.sh
