#!/usr/bin/env bash
# Installs lshloc's build and test dependencies from Debian 12 packages.
# Idempotent and quiet when everything is already there. `--peers` adds the
# optional peer indexes of the database benchmark.
set -euo pipefail
packages=(build-essential cmake pkg-config libeigen3-dev zlib1g-dev libcli11-dev nlohmann-json3-dev
          libgtest-dev libgmock-dev libbenchmark-dev libcairo2-dev libyaml-dev libpng-dev python3 clang-format
          pybind11-dev python3-dev python3-numpy python3-pytest clang libclang-rt-14-dev ninja-build
          redis-server libhiredis-dev python3-zstandard python3-lz4
          # ROS 1 (Debian's): the lshloc_ros_node build and its test against a real master and rosbag play
          libroscpp-dev libtf2-ros-dev libsensor-msgs-dev libnav-msgs-dev libgeometry-msgs-dev libstd-srvs-dev
          libstd-msgs-dev librosbag-dev ros-core-dev python3-rosbag python3-rospy python3-tf2-msgs
          python3-sensor-msgs python3-nav-msgs python3-geometry-msgs python3-std-msgs)
# --peers: also the indexes bench/lsh_peers_bench compares against (BENCHMARKS.md).
[ "${1:-}" = "--peers" ] && packages+=(libhnswlib-dev libfaiss-dev libflann-dev liblz4-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "setup: installing ${missing[*]}" >&2
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
