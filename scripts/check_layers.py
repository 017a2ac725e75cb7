#!/usr/bin/env python3
"""Checks that no area of lshloc includes a header of an area above it.

Areas, lowest first (docs/design.md "Layers"). An area may include its own
headers and those of the areas it lists here; apps, tests and benches may
include anything. Run from anywhere; exits 1 and names file, line and the
offending include on a violation.
"""
import pathlib
import re
import sys

ALLOWED = {
    "common": set(),
    "geometry": {"common"},
    "appearance": {"common", "geometry"},
    "matching": {"common", "geometry", "appearance"},
    "slam": {"common", "geometry"},
    "localization": {"common", "geometry", "appearance", "matching", "slam"},
    "runtime": {"common", "geometry", "appearance", "matching", "slam", "localization"},
    "io": {"common", "geometry", "appearance", "matching", "slam", "localization", "runtime"},
    "figures": {"common", "geometry"},
    "eval": {"common", "geometry", "appearance", "matching", "slam", "localization", "runtime", "io"},
    "sim": {"common", "geometry", "appearance", "matching", "slam", "localization", "runtime"},
    "fleet": {"common", "geometry", "appearance", "matching", "slam", "localization", "runtime", "io"},
}
INCLUDE = re.compile(r'^\s*#\s*include\s+"lshloc/([a-z_]+)/[^"]+"')


def main() -> int:
    root = pathlib.Path(__file__).resolve().parent.parent
    problems = []
    checked = 0
    for top in ("include/lshloc", "src"):
        for path in sorted((root / top).rglob("*.[ch]pp")):
            area = path.relative_to(root / top).parts[0]
            if area not in ALLOWED:
                problems.append(f"{path.relative_to(root)}: unknown area '{area}' (expected one of {sorted(ALLOWED)})")
                continue
            checked += 1
            for number, line in enumerate(path.read_text().splitlines(), 1):
                m = INCLUDE.match(line)
                if m and m.group(1) != area and m.group(1) not in ALLOWED[area]:
                    problems.append(f"{path.relative_to(root)}:{number}: area '{area}' includes '{m.group(1)}' "
                                    f"(expected only {sorted(ALLOWED[area] | {area})})")
    for p in problems:
        print(p)
    print(f"check_layers: {checked} files, {len(problems)} violations")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
