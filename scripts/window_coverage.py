#!/usr/bin/env python3
"""How much of a target window the map's robots drove: for each ground-truth
pose of the window (raw scans START .. START+LENGTH-1 of BUILDING), the
distance to the nearest corrected pose that the protocol keeps in the map
(outside the window and GUARD seconds around it), as docs/design.md section 6
splits a log. Reads the raw log's scan time stamps and the poses file.

    scripts/window_coverage.py aces 3000 [--length 1000] [--guard 60] [--data ../shared/data]

Prints how many window poses lie within 1 m and 2 m of a map pose, and the
distance of the last one.
"""
import argparse
import gzip
import math
import os
import sys

RAW = {"fr079": "fr079/fr079.recon-from-bag.log.gz", "fr101": "fr101/fr101.carmen.log.gz",
       "intel": "intel/intel.recon-from-bag.log.gz", "aces": "aces/aces.recon-from-bag.log.gz",
       "mit-csail": "mit-csail/mit-csail.clf.gz"}
POSES = {"fr079": "fr079/fr079.gfs-poses-at-bag-stamps.txt", "fr101": "fr101/fr101.gfs-poses-at-raw-stamps.txt",
         "intel": "intel/intel.gfs-poses-at-bag-stamps.txt", "aces": "aces/aces.gfs-poses-at-bag-stamps.txt",
         "mit-csail": "mit-csail/csail.gfs-poses-at-clf-stamps.txt"}


def raw_stamps(path):
    stamps = []
    with gzip.open(path, "rt") as f:
        for n, line in enumerate(f, 1):
            a = line.split()
            if not a or a[0] != "FLASER":
                continue
            beams = int(a[1])
            if len(a) < beams + 9:
                sys.exit(f"{path}:{n}: FLASER line too short for {beams} beams")
            stamps.append(float(a[beams + 8]))
    return stamps


def data_lines(path):
    """(line number, fields) of each line of a text file that is neither blank nor a # comment."""
    with open(path) as f:
        for n, line in enumerate(f, 1):
            if line.strip() and not line.startswith("#"):
                yield n, line.split()


def truth_poses(path):
    """[(raw stamp, x, y, theta)] of a ground-truth poses file, in file order."""
    poses = []
    for n, a in data_lines(path):
        try:
            t, x, y, theta = map(float, a[:4])
        except ValueError:
            sys.exit(f"{path}:{n}: expected 'timestamp x y theta'")
        poses.append((t, x, y, theta))
    return poses


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("building", choices=sorted(RAW))
    p.add_argument("start", type=int)
    p.add_argument("--length", type=int, default=1000)
    p.add_argument("--guard", type=float, default=60.0, help="[s] map scans this close to the window are left out")
    p.add_argument("--data", default=os.environ.get("LSHLOC_DATA", "../shared/data"))
    a = p.parse_args()
    stamps = raw_stamps(os.path.join(a.data, RAW[a.building]))
    if not 0 <= a.start < len(stamps):
        sys.exit(f"start {a.start} outside the log's {len(stamps)} scans")
    t0, t1 = stamps[a.start], stamps[min(a.start + a.length, len(stamps)) - 1]
    poses = truth_poses(os.path.join(a.data, POSES[a.building]))
    window = [q for q in poses if t0 <= q[0] <= t1]
    kept = [q for q in poses if q[0] < t0 - a.guard or q[0] > t1 + a.guard]
    if not window or not kept:
        sys.exit("no ground-truth pose in the window, or none left for the map")
    d = [min(math.hypot(w[1] - m[1], w[2] - m[2]) for m in kept) for w in window]
    print(f"{a.building} start {a.start}: {len(window)} ground-truth poses in the window, {len(kept)} map poses; "
          f"within 1 m of a map pose: {sum(x < 1 for x in d)}, within 2 m: {sum(x < 2 for x in d)}; "
          f"last pose {d[-1]:.1f} m from the nearest")


if __name__ == "__main__":
    main()
