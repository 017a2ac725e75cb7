#!/usr/bin/env python3
"""Whether two `eval --trace` CSVs hold the same estimates, one written before the one estimate schema
(timestamp, submap as an id, theta [rad], mean_score, has_estimate) and one after (time, submap_id, heading_deg,
score; an empty submap for no estimate), or both in either: every column the two share by name is compared
as text, the renamed ones through their new names, headings to the 1e-3 degree the new schema prints.
Usage: trace_identity.py OLD.csv NEW.csv [LABEL]   (exit 0: the same; prints one line)"""
import csv
import math
import sys

RENAMED = {"timestamp": "time", "submap": "submap_id", "mean_score": "score"}


def main():
    old = list(csv.DictReader(open(sys.argv[1])))
    new = list(csv.DictReader(open(sys.argv[2])))
    label = sys.argv[3] if len(sys.argv) > 3 else sys.argv[2]
    # An old-schema trace against a new-schema one: compare through the renames; otherwise by name alone.
    before = "has_estimate" in old[0] and "submap_id" not in old[0] and "submap_id" in new[0]
    renamed = RENAMED if before else {}
    shared = [c for c in old[0] if c in new[0] and c not in renamed]
    differences = 0
    for a, b in zip(old, new):
        differences += sum(a[c] != b[c] for c in shared)
        differences += sum(a[o] != b[n] for o, n in renamed.items())
        if before:
            differences += (a["has_estimate"] == "1") != (b["submap"] != "")
            if a["theta"]:
                differences += abs(math.degrees(float(a["theta"])) - float(b["heading_deg"])) > 1.5e-3
            else:
                differences += b["heading_deg"] != ""
    same = differences == 0 and len(old) == len(new)
    print(f"{label}: {len(old)} / {len(new)} rows, {len(shared)} shared and {len(renamed)} renamed columns, "
          f"{differences} differences: {'same' if same else 'DIFFERENT'}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
