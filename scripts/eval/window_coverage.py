#!/usr/bin/env python3
"""How much of a target window the map's robots drove: for each ground-truth
pose of the window (raw scans START .. START+LENGTH-1 of BUILDING), the
distance to the nearest corrected pose that the protocol keeps in the map
(outside the window and GUARD seconds around it), as docs/design.md section 6
splits a log. Reads the raw log's scan time stamps and the poses file.

    scripts/eval/window_coverage.py aces 3000 [--length 1000] [--guard 60] [--data ../shared/data]
    scripts/eval/window_coverage.py mit-csail --sweep

Prints how many window poses lie within 1 m and 2 m of a map pose, and the
distance of the last one. --sweep: a Markdown table over the 20 evenly spaced
starts of the start sweep (scripts/eval/sweep.sh starts), with the share within
2 m (the live protocol's "mapped") and the nearest any window pose comes.
--endpoints adds what the map's scans saw, whatever scores them: each window
ground-truth scan's laser endpoints (ranges under 30 m, at its true pose)
that lie within one 0.15 m cell of a map scan's endpoint; the table gives
their median and largest share over the window and how many scans reach 30%.

    scripts/eval/window_coverage.py mit-csail --sweep --endpoints
"""
import argparse
import bisect
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


def raw_scans(path):
    """([time stamp], [ranges]) of the FLASER scans of a raw log, in log order."""
    stamps, ranges = [], []
    with gzip.open(path, "rt") as f:
        for n, line in enumerate(f, 1):
            a = line.split()
            if not a or a[0] != "FLASER":
                continue
            beams = int(a[1])
            if len(a) < beams + 9:
                sys.exit(f"{path}:{n}: FLASER line too short for {beams} beams")
            stamps.append(float(a[beams + 8]))
            ranges.append([float(r) for r in a[2:2 + beams]])
    return stamps, ranges


CELL = 0.15  # [m] the endpoint grid's cell


def endpoint_cells(ranges, pose):
    """Grid cells of a scan's endpoints under 30 m (FLASER: n beams over 180 degrees, right to left)."""
    x, y, theta = pose
    n = len(ranges)
    cells = []
    for i, r in enumerate(ranges):
        if 0 < r < 30:
            a = theta - math.pi / 2 + i * math.pi / max(n - 1, 1)
            cells.append((math.floor((x + r * math.cos(a)) / CELL), math.floor((y + r * math.sin(a)) / CELL)))
    return cells


def scan_of(stamps, t):
    """Index of the raw scan stamped within 1 ms of t (the poses file's key), or None."""
    i = bisect.bisect_left(stamps, t)
    near = [j for j in (i - 1, i) if 0 <= j < len(stamps) and abs(stamps[j] - t) <= 0.001]
    return min(near, key=lambda j: abs(stamps[j] - t)) if near else None


def endpoint_overlap(stamps, ranges, window, kept):
    """Per window pose with its raw scan: the share of its endpoints within a cell of a map endpoint."""
    seen = set()
    for q in kept:
        j = scan_of(stamps, q[0])
        if j is not None:
            seen.update(endpoint_cells(ranges[j], q[1:]))
    shares = []
    for w in window:
        j = scan_of(stamps, w[0])
        cells = endpoint_cells(ranges[j], w[1:]) if j is not None else []
        if cells:
            hit = sum(any((cx + dx, cy + dy) in seen for dx in (-1, 0, 1) for dy in (-1, 0, 1)) for cx, cy in cells)
            shares.append(hit / len(cells))
    return shares


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


SWEEP_TOTAL = {"fr079": 4934, "fr101": 4758, "intel": 13631, "aces": 7374, "mit-csail": 1988}


def coverage(stamps, poses, start, length, guard):
    """(window poses, map poses, each window pose's distance to the nearest map pose), or None."""
    t0, t1 = stamps[start], stamps[min(start + length, len(stamps)) - 1]
    window = [q for q in poses if t0 <= q[0] <= t1]
    kept = [q for q in poses if q[0] < t0 - guard or q[0] > t1 + guard]
    if not window or not kept:
        return None
    return window, kept, [min(math.hypot(w[1] - m[1], w[2] - m[2]) for m in kept) for w in window]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("building", choices=sorted(RAW))
    p.add_argument("start", type=int, nargs="?")
    p.add_argument("--sweep", action="store_true", help="the 20 starts of the start sweep instead of one")
    p.add_argument("--length", type=int, default=1000)
    p.add_argument("--guard", type=float, default=60.0, help="[s] map scans this close to the window are left out")
    p.add_argument("--endpoints", action="store_true", help="with --sweep: the window scans' endpoints the map saw")
    p.add_argument("--data", default=os.environ.get("LSHLOC_DATA", "../shared/data"))
    a = p.parse_args()
    if (a.start is None) == (not a.sweep):
        sys.exit("give a START or --sweep")
    stamps, ranges = raw_scans(os.path.join(a.data, RAW[a.building]))
    poses = truth_poses(os.path.join(a.data, POSES[a.building]))
    length = min(a.length, len(stamps))
    if a.sweep:
        extra = " endpoints seen: median | largest | scans >= 30% |" if a.endpoints else ""
        print("| start | map poses | window poses | within 2 m | nearest [m] | last pose from the map [m] |" + extra)
        print("|---|---|---|---|---|---|" + "---|---|---|" * a.endpoints)
        for i in range(20):
            start = i * (SWEEP_TOTAL[a.building] - length) // 19
            c = coverage(stamps, poses, start, length, a.guard)
            if c is None:
                print(f"| {start} | - | - | - | - | - |" + " - | - | - |" * a.endpoints)
                continue
            window, kept, d = c
            row = (f"| {start} | {len(kept)} | {len(window)} | {sum(x < 2 for x in d) / len(d):.2f} | "
                   f"{min(d):.1f} | {d[-1]:.1f} |")
            if a.endpoints:
                e = sorted(endpoint_overlap(stamps, ranges, window, kept))
                row += (f" {e[len(e) // 2]:.2f} | {e[-1]:.2f} | {sum(v >= 0.3 for v in e)} |" if e
                        else " - | - | - |")
            print(row)
        return
    if not 0 <= a.start < len(stamps):
        sys.exit(f"start {a.start} outside the log's {len(stamps)} scans")
    c = coverage(stamps, poses, a.start, a.length, a.guard)
    if c is None:
        sys.exit("no ground-truth pose in the window, or none left for the map")
    window, kept, d = c
    print(f"{a.building} start {a.start}: {len(window)} ground-truth poses in the window, {len(kept)} map poses; "
          f"within 1 m of a map pose: {sum(x < 1 for x in d)}, within 2 m: {sum(x < 2 for x in d)}; "
          f"last pose {d[-1]:.1f} m from the nearest")


if __name__ == "__main__":
    main()
