#!/usr/bin/env bash
# The fleet's functional and cluster cases (scripts/fleet_test.py) as a test:
# 4 mapper processes publish fr079's default scenario (R = 4, --smoke) into the test's
# own Redis on loopback, 2 localizers must localize it, and the same through a
# 3-master Redis Cluster must give byte-identical per-scan estimates.
# Skips when the logs or redis-server are absent, and under sanitizers (the
# Release run covers it; the sanitized one would take minutes).
# Usage: fleet_loopback_test.sh LSHLOC DATA_DIR
set -euo pipefail
LSHLOC=$1 DATA=$2
[ -d "$DATA" ] || { echo "fleet_loopback_test: $DATA not found: skipped"; exit 0; }
command -v redis-server >/dev/null || { echo "fleet_loopback_test: redis-server not found (scripts/setup.sh installs it): skipped"; exit 0; }
[ "${LSHLOC_SANITIZED:-0}" = 1 ] && { echo "fleet_loopback_test: skipped under sanitizers"; exit 0; }
LSHLOC=$LSHLOC LSHLOC_DATA=$DATA python3 "$(dirname "$0")/../scripts/fleet_test.py" --cases functional,cluster --smoke
