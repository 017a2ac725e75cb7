#!/usr/bin/env python3
"""Confident scans of a `lshloc localize` run on a whole raw log, against ground truth.

    scripts/eval/whole_log_truth.py T.tum.csv RAW_LOG CORRECTED_LOG POSES_FILE [--submap NAME]

T.tum.csv is the CSV that `localize --out T.tum` writes beside the TUM file.
A confident scan is wrong when it is more than 2 m or 10 degrees off, or in a
submap whose name lacks NAME (default: the corrected log's file name).

Two joins of the ground truth to the scans are reported:
  by time   each confident row takes the pose whose stamp is within 2 ms of
            its own (as ../shared/acceptance/confidence does);
  own scan  each pose goes to the one raw scan with its ranges (the poses
            file's k-th line is the corrected log's k-th scan, whose ranges
            are the raw scan's). intel's raw log bunches stamps about 1 ms
            apart, so the join by time also gives poses to neighbouring scans
            that the robot saw at another heading.
"""
import argparse
import bisect
import csv
import gzip
import math
import sys


def flaser_scans(path):
    """(stamp, ranges) of each FLASER line, in log order."""
    out = []
    with gzip.open(path, "rt") if path.endswith(".gz") else open(path) as f:
        for lineno, line in enumerate(f, 1):
            if not line.startswith("FLASER"):
                continue
            fields = line.split()
            try:
                n = int(fields[1])
                out.append((float(fields[8 + n]), [float(v) for v in fields[2:2 + n]]))
            except (ValueError, IndexError):
                sys.exit(f"{path}:{lineno}: expected FLASER n r1..rn x y theta odom_x odom_y odom_theta ipc_timestamp")
    if not out:
        sys.exit(f"{path}: no FLASER lines")
    return out


def read_poses(path):
    poses = []
    for lineno, line in enumerate(open(path), 1):
        if not line.strip() or line.startswith("#"):
            continue
        try:
            t, x, y, theta = map(float, line.split()[:4])
        except ValueError:
            sys.exit(f"{path}:{lineno}: expected 'timestamp x y theta'")
        poses.append((t, x, y, theta))
    return poses


def same_ranges(a, b):
    return len(a) == len(b) and all(abs(x - y) <= 0.006 for x, y in zip(a, b))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("raw_log")
    ap.add_argument("corrected_log")
    ap.add_argument("poses_file")
    ap.add_argument("--submap", help="the target's submap name contains this (default: the corrected log's name)")
    a = ap.parse_args()
    submap = a.submap or a.corrected_log.rsplit("/", 1)[-1]
    raw = flaser_scans(a.raw_log)
    corrected = flaser_scans(a.corrected_log)
    poses = read_poses(a.poses_file)
    if len(poses) != len(corrected):
        sys.exit(f"{a.poses_file}: {len(poses)} poses but {a.corrected_log} has {len(corrected)} scans")
    rows = list(csv.DictReader(open(a.csv)))
    if rows and not {"log_scan", "time", "submap", "x", "y", "heading_deg", "confident"} <= rows[0].keys():
        sys.exit(f"{a.csv}: expected the columns log_scan,time,submap,x,y,heading_deg,confident")

    def wrong(row, pose):
        dh = math.degrees(math.remainder(math.radians(float(row["heading_deg"])) - pose[3], 2 * math.pi))
        far = math.hypot(float(row["x"]) - pose[1], float(row["y"]) - pose[2]) > 2.0
        return submap not in row["submap"] or far or abs(dh) > 10.0

    confident = [r for r in rows if r["confident"].strip() in ("1", "true")]
    by_stamp = sorted(poses)
    stamps = [p[0] for p in by_stamp]
    joined = bad = 0
    for r in confident:
        t = float(r["time"])
        i = bisect.bisect_left(stamps, t)
        dt, j = min((abs(stamps[j] - t), j) for j in (i - 1, i) if 0 <= j < len(stamps))
        if dt > 0.002:
            continue
        joined += 1
        bad += wrong(r, by_stamp[j])

    raw_stamps = [s[0] for s in raw]
    by_scan = {int(r["log_scan"]): r for r in confident}
    own = own_bad = unmatched = 0
    bad_scans = []
    for k, pose in enumerate(poses):
        i = bisect.bisect_left(raw_stamps, pose[0] - 0.01)
        near = [j for j in range(max(0, i - 50), min(len(raw), i + 50))
                if abs(raw_stamps[j] - pose[0]) <= 0.01 and same_ranges(raw[j][1], corrected[k][1])]
        if len(near) != 1:
            unmatched += 1
            continue
        r = by_scan.get(near[0])
        if r is None:
            continue
        own += 1
        if wrong(r, pose):
            own_bad += 1
            bad_scans.append(near[0])
    print(f"by time (2 ms): {bad} of {joined} confident ground-truth scans more than 10 deg or 2 m off")
    print(f"own scan: {own_bad} of {own} confident ground-truth scans more than 10 deg or 2 m off"
          f" ({unmatched} poses without exactly one raw scan of their ranges){': ' if bad_scans else ''}"
          f"{' '.join(map(str, bad_scans[:20]))}")


if __name__ == "__main__":
    main()
