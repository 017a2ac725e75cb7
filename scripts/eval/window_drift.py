#!/usr/bin/env python3
"""How far the target's local map drifts over a localization window: runs
`lshloc slam --no-loop-closure --localizer-matcher` (the localizer's scan
matcher alone, with its settings) over a
building's raw log, then, for WINDOWS evenly spaced windows of LENGTH raw
scans (the many-starts windows of RESULTS.md), compares the motion from the
window's first to its last ground-truth scan with the ground truth's: the
heading error [deg] and the end-point error [m]. Extra arguments go to
`lshloc slam` (e.g. --config FILE.json with {"matcher": {"normal_min_points": 4}},
the mapping default).

    scripts/eval/window_drift.py aces [--per-window] [--lshloc build/bin/lshloc] [--data ../shared/data] [-- --config m.json]
"""
import argparse
import math
import os
import statistics
import subprocess
import sys
import tempfile

from window_coverage import POSES, RAW, data_lines, truth_poses


def wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def relative(a, b):
    """b in the frame of a, both (x, y, theta)."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    c, s = math.cos(a[2]), math.sin(a[2])
    return c * dx + s * dy, -s * dx + c * dy, wrap(b[2] - a[2])


def read_tum(path):
    """[(stamp rounded to 10 ms, (x, y, theta))] of a TUM trajectory, in file order."""
    out = []
    for n, a in data_lines(path):
        try:
            theta = 2.0 * math.atan2(float(a[6]), float(a[7]))
            out.append((round(float(a[0]), 2), (float(a[1]), float(a[2]), theta)))
        except (IndexError, ValueError):
            sys.exit(f"{path}:{n}: expected 'timestamp x y z qx qy qz qw'")
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("building", choices=sorted(RAW))
    p.add_argument("--length", type=int, default=1000)
    p.add_argument("--windows", type=int, default=20)
    p.add_argument("--lshloc", default="build/bin/lshloc")
    p.add_argument("--data", default=os.environ.get("LSHLOC_DATA", "../shared/data"))
    p.add_argument("--per-window", action="store_true", help="also print each window's start and drift")
    p.add_argument("slam_args", nargs="*", help="passed to lshloc slam")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tum = os.path.join(tmp, "local.tum")
        cmd = [a.lshloc, "slam", "--log", os.path.join(a.data, RAW[a.building]), "--no-loop-closure",
               "--localizer-matcher", "--out", tum]
        subprocess.run(cmd + a.slam_args, check=True, stdout=subprocess.DEVNULL)
        estimate = read_tum(tum)
    truth = {round(t, 2): (x, y, theta) for t, x, y, theta in truth_poses(os.path.join(a.data, POSES[a.building]))}
    if len(estimate) < a.length:
        sys.exit(f"the log has {len(estimate)} scans, fewer than one window of {a.length}")
    headings, ends = [], []
    for k in range(a.windows):
        first = k * (len(estimate) - a.length) // max(1, a.windows - 1)
        judged = [(t, pose) for t, pose in estimate[first:first + a.length] if t in truth]
        if len(judged) < 2:
            continue
        (ta, ea), (tb, eb) = judged[0], judged[-1]
        e, g = relative(ea, eb), relative(truth[ta], truth[tb])
        headings.append(abs(math.degrees(wrap(e[2] - g[2]))))
        ends.append(math.hypot(e[0] - g[0], e[1] - g[1]))
        if a.per_window:
            print(f"start {first}: heading drift {headings[-1]:.2f} deg, end-point error {ends[-1]:.2f} m")
    if not headings:
        sys.exit("no window holds two ground-truth scans")
    print(f"{a.building}: {len(headings)} windows of {a.length} scans; heading drift [deg] median "
          f"{statistics.median(headings):.1f} mean {statistics.mean(headings):.1f} max {max(headings):.1f}; "
          f"end-point error [m] median {statistics.median(ends):.2f} mean {statistics.mean(ends):.2f} "
          f"max {max(ends):.2f}")


if __name__ == "__main__":
    main()
