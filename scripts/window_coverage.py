#!/usr/bin/env python3
"""How much of a target window the map side of its own building can explain.

For each start of the 100-start sweep (20 evenly spaced windows of 1000 raw
scans per building, as `scripts/sweep.sh starts` and
`../shared/acceptance/confidence --full` run them), this reads the raw log's
scan stamps and the poses file (the corrected pose of each corrected scan,
keyed by its raw stamp), splits the poses as the scenario does (a corrected
scan is a map scan when its stamp lies more than the 60 s guard outside the
window, docs/design.md section 6) and prints, per window: the map scans, the
share of the window's ground-truth poses within 2 m of a map scan pose (the
live protocol's "mapped"), the nearest any window pose comes to a map pose,
and how far the window's last ground-truth pose lies from the map.

  scripts/window_coverage.py [BUILDING ...]   (default mit-csail; LSHLOC_DATA
                                               or ../shared/data)
Reads files only; pure Python."""
import gzip
import math
import os
import sys

FILES = {  # raw log, poses file, scans in the raw log (the sweep's list)
    "fr079": ("fr079/fr079.recon-from-bag.log.gz", "fr079/fr079.gfs-poses-at-bag-stamps.txt", 4934),
    "fr101": ("fr101/fr101.carmen.log.gz", "fr101/fr101.gfs-poses-at-raw-stamps.txt", 4758),
    "intel": ("intel/intel.recon-from-bag.log.gz", "intel/intel.gfs-poses-at-bag-stamps.txt", 13631),
    "aces": ("aces/aces.recon-from-bag.log.gz", "aces/aces.gfs-poses-at-bag-stamps.txt", 7374),
    "mit-csail": ("mit-csail/mit-csail.clf.gz", "mit-csail/csail.gfs-poses-at-clf-stamps.txt", 1988),
}
GUARD_S, MAPPED_M, LENGTH = 60.0, 2.0, 1000


def raw_stamps(path):
    """The stamp of every laser line, in log order (CARMEN lines end with
    ipc_timestamp ipc_hostname logger_timestamp)."""
    out = []
    with gzip.open(path, "rt", errors="replace") as f:
        for line in f:
            t = line.split()
            if t and t[0] in ("FLASER", "RLASER", "ROBOTLASER1", "RAWLASER1"):
                out.append(float(t[-3]))
    return out


def poses(path):
    with open(path) as f:
        return [tuple(map(float, l.split()[:3])) for l in f if l.strip() and not l.startswith("#")]


def main():
    data = os.environ.get("LSHLOC_DATA", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data"))
    buildings = sys.argv[1:] or ["mit-csail"]
    print("| building | start | map scans | window truth poses | mapped (within 2 m) | nearest [m] | last pose from the map [m] |")
    print("|---|---|---|---|---|---|---|")
    for b in buildings:
        raw_rel, poses_rel, total = FILES[b]
        stamps = raw_stamps(os.path.join(data, raw_rel))
        truth = poses(os.path.join(data, poses_rel))
        length = min(LENGTH, len(stamps))
        for i in range(20):
            s0 = i * (total - length) // 19
            t0, t1 = stamps[s0], stamps[min(s0 + length, len(stamps)) - 1]
            inside = [p for p in truth if t0 <= p[0] <= t1]
            mapped = [p for p in truth if p[0] < t0 - GUARD_S or p[0] > t1 + GUARD_S]
            if not inside or not mapped:
                print(f"| {b} | {s0} | {len(mapped)} | {len(inside)} | - | - | - |")
                continue
            dist = [min(math.hypot(p[1] - q[1], p[2] - q[2]) for q in mapped) for p in inside]
            share = sum(d < MAPPED_M for d in dist) / len(dist)
            print(f"| {b} | {s0} | {len(mapped)} | {len(inside)} | {share:.2f} | {min(dist):.1f} | {dist[-1]:.1f} |")


if __name__ == "__main__":
    main()
