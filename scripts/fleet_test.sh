#!/usr/bin/env bash
# The fleet's loopback test (docs/fleet.md): its own Redis servers, mapper and
# localizer processes, faults; one JSON line last. See scripts/fleet_test.py.
# Usage: LSHLOC=build/bin/lshloc scripts/fleet_test.sh
exec python3 "$(dirname "$0")/fleet_test.py" "$@"
