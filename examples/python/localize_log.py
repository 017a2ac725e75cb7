#!/usr/bin/env python3
"""Localize a target robot's CARMEN log in a map of mapped logs, from Python.

    PYTHONPATH=build/python python3 examples/python/localize_log.py \
        --map ../shared/data/intel/intel.gfs.log.gz --map ../shared/data/aces/aces-corrected.log.gz \
        --target ../shared/data/intel/intel.recon-from-bag.log.gz --start 5000 --length 300
"""
import argparse
import math

import lshloc

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--map", action="append", required=True, help="mapped (corrected) log; repeat per submap")
parser.add_argument("--target", required=True, help="the target robot's raw log")
parser.add_argument("--start", type=int, default=0)
parser.add_argument("--length", type=int, default=300)
args = parser.parse_args()

gmap = lshloc.GlobalMap()
submaps = [(path, lshloc.read_carmen_log(path).scans) for path in args.map]
ids = [gmap.add_submap(path.split("/")[-1]) for path, _ in submaps]
for i in range(max(len(scans) for _, scans in submaps)):  # mapper robots in parallel: one scan each in turn
    for sid, (_, scans) in zip(ids, submaps):
        if i < len(scans):
            gmap.add_scan(sid, scans[i], scans[i].pose)
print(f"map: {gmap.stats()['features']} features in {gmap.submap_count} submaps")

target = lshloc.read_carmen_log(args.target)
window = target.scans[args.start:args.start + args.length]
if not window:
    parser.error(f"--start {args.start} --length {args.length}: no scans there ({args.target} has {len(target.scans)})")
localizer = lshloc.Localizer(gmap, laser_offset=target.laser_offset)
first = None
for n, scan in enumerate(window):
    estimate = localizer.add_scan(scan)
    if estimate["localized"] and first is None:
        first = n
if estimate["localized"]:
    x, y, theta = estimate["pose"]
    print(f"localized in {estimate['submap_name']}: x {x:.3f} m, y {y:.3f} m, heading {math.degrees(theta):.1f} deg "
          f"(confident since scan {first})")
else:
    print("not localized: " + (", ".join(estimate["not_confident_because"]) or "no estimate"))
