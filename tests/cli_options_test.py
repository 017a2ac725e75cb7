#!/usr/bin/env python3
"""Every numeric option of every command, given nan, -1, 0 and 1e12: each run
must end within 10 s and 1 GiB, either with a clean refusal (exit 1..123 and a
message on stderr) or with exit 0. Options are found in each command's --help
(CLI11's UINT / INT / FLOAT type names), so a new option joins the sweep by
itself. Commands that need the shared logs are swept when they are present.

Usage: cli_options_test.py LSHLOC [DATA_DIR]   ($LSHLOC_DATA wins; VERBOSE=1 prints every run)"""
import concurrent.futures
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile

LSHLOC = os.path.abspath(sys.argv[1])
DATA = os.environ.get("LSHLOC_DATA") or (sys.argv[2] if len(sys.argv) > 2 else "")
VALUES = ["nan", "-1", "0", "1e12"]
# Under sanitizers (LSHLOC_SANITIZED, set by ctest) runs are slower and ASan
# reserves terabytes of address space: a longer limit and no address cap.
SANITIZED = bool(os.environ.get("LSHLOC_SANITIZED"))
LIMIT_S = 30 if SANITIZED else 10
LIMIT_BYTES = 1 << 30


def run(args, cwd):
    def limits():
        # A runaway allocation fails (std::bad_alloc: exit 3 and a message) instead of swapping.
        if not SANITIZED:
            resource.setrlimit(resource.RLIMIT_AS, (4 * LIMIT_BYTES, 4 * LIMIT_BYTES))
    rss_file = os.path.join(cwd, "rss")
    p = subprocess.Popen(["/usr/bin/time", "-f", "%M", "-o", rss_file, LSHLOC] + args, cwd=cwd,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=limits)
    try:
        _, err = p.communicate(timeout=LIMIT_S)
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        return "timeout", b"", 0
    with open(rss_file) as f:
        lines = f.read().split()
    return p.returncode, err, int(lines[-1]) * 1024 if lines else 0


def numeric_options(command):
    text = subprocess.run([LSHLOC] + command + ["--help"], capture_output=True, text=True, check=True).stdout
    return sorted(set(re.findall(r"^\s+(--[a-z0-9-]+) (?:UINT|INT|FLOAT)", text, re.M)))


def main():
    work = tempfile.mkdtemp(prefix="lshloc-options-")
    try:
        return sweep(work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def sweep(work):
    sim = os.path.join(work, "sim")
    subprocess.run([LSHLOC, "simulate", "--out", sim, "--buildings", "1", "--seed", "5", "--scans", "300"],
                   check=True, capture_output=True)
    corrected = os.path.join(sim, "sim-5-000", "sim-5-000-corrected.log.gz")
    raw = os.path.join(sim, "sim-5-000", "sim-5-000.log.gz")
    subprocess.run([LSHLOC, "map", "to-grid", corrected, "--out", os.path.join(work, "grid")], check=True,
                   capture_output=True)
    grid = os.path.join(work, "grid.yaml")
    saved = os.path.join(work, "base.map")
    subprocess.run([LSHLOC, "map", "build", corrected, "--out", saved], check=True, capture_output=True)
    coarse = os.path.join(work, "coarse.map")
    subprocess.run([LSHLOC, "map", "from-grid", grid, "--out", coarse, "--grid-spacing", "3"], check=True,
                   capture_output=True)

    # Each command with the smallest arguments that make a valid, short run (grids ray-cast coarsely).
    commands = {
        ("demo",): ["--buildings", "2", "--target", "1", "--map-scans", "150", "--target-scans", "30"],
        # A grid map saved once, coarsely ray-cast: localize sets no lattice itself.
        ("localize",): ["--map", coarse, "--map", corrected, "--target", raw, "--length", "20"],
        ("simulate",): ["--out", os.path.join(work, "simout"), "--scans", "40"],
        ("bench", "matching"): ["--viewpoints", "300", "--warm-up", "10"],
        ("bench", "scale"): ["--submaps", "1", "--map-scans", "100", "--target-scans", "20", "--targets", "1",
                              "--no-random"],
        ("bench", "shards"): ["--submaps", "2", "--shards", "1", "--targets", "1", "--map-scans", "100",
                              "--target-scans", "20"],
        # (into a submap of its own: the map holds this log already)
        ("map", "append"): [os.path.join(work, "append.map"), corrected, "--count", "10", "--submap", "more"],
        ("map", "to-grid"): [corrected, "--out", os.path.join(work, "g2")],
        ("map", "from-grid"): [grid, "--out", os.path.join(work, "fromgrid.map"), "--grid-spacing", "3"],
        ("map", "build"): [corrected, "--out", os.path.join(work, "build.map")],
    }
    if DATA and os.path.isdir(os.path.join(DATA, "aces")):
        commands[("eval",)] = ["--building", "aces", "--length", "20", "--json"]
        # The grid options again, now used (each run ray-casts the submaps' grids: coarse, to stay short).
        commands[("eval", "--grid-maps")] = ["--building", "aces", "--length", "20", "--json", "--grid-spacing", "3"]
        commands[("recall",)] = ["--building", "aces", "--length", "20", "--no-exact", "--json"]
        commands[("bench", "robots")] = ["--building", "aces", "--submaps", "1", "--length", "20", "--threads", "1",
                                         "--rounds", "1"]
    else:
        print("cli_options_test: shared data directory not found: eval and recall not swept")

    cases = []
    for command, base in commands.items():
        words = [w for w in command if not w.startswith("--")]
        flags = [w for w in command if w.startswith("--")]
        for option in numeric_options(words):
            if flags == ["--grid-maps"] and not option.startswith("--grid-"):
                continue  # swept without --grid-maps already
            for value in VALUES:
                args = list(words) + flags
                # The swept option replaces the base's value of the same option.
                b = list(base)
                if option in b:
                    i = b.index(option)
                    del b[i:i + 2]
                cases.append((command, option, value, args + b + [option, value]))

    def one(case):
        command, option, value, args = case
        cwd = tempfile.mkdtemp(dir=work)
        if command == ("map", "append"):
            # A fresh copy of the saved map per run.
            with open(saved, "rb") as src, open(args[2], "wb") as dst:
                dst.write(src.read())
        rc, err, rss = run(args, cwd)
        label = f"{' '.join(command)} {option} {value}"
        if rc == "timeout":
            return f"FAIL {label}: still running after {LIMIT_S} s"
        if rc < 0 or rc >= 124:
            return f"FAIL {label}: exit {rc} (a signal or crash): {err[-300:].decode(errors='replace')}"
        if rc != 0 and not err.strip():
            return f"FAIL {label}: exit {rc} without a message"
        if rss > LIMIT_BYTES:
            return f"FAIL {label}: {rss >> 20} MiB"
        if os.environ.get("VERBOSE"):
            print(f"{label}: exit {rc}: {err.decode(errors='replace').strip().splitlines()[-1:] if err.strip() else ''}")
        return "ran" if rc == 0 else "refused"

    # Each base run must itself succeed, or the sweep would only see refusals.
    for command, base in commands.items():
        words = [w for w in command if not w.startswith("--")]
        flags = [w for w in command if w.startswith("--")]
        cwd = tempfile.mkdtemp(dir=work)
        if command == ("map", "append"):
            with open(saved, "rb") as src, open(base[0], "wb") as dst:
                dst.write(src.read())
        rc, err, _ = run(words + flags + base, cwd)
        if rc != 0:
            print(f"FAIL the base run of {' '.join(command)} exits {rc}: {err[-300:].decode(errors='replace')}")
            return 1

    # Distinct files per case except the append copies, which are per command: run those alone.
    appends = [c for c in cases if c[0] == ("map", "append")]
    others = [c for c in cases if c[0] != ("map", "append")]
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        outcomes = list(pool.map(one, others))
    outcomes += list(map(one, appends))
    failures = [o for o in outcomes if o.startswith("FAIL")]
    for f in failures:
        print(f)
    print(f"cli_options_test: {len(cases)} runs over {len(set((c[0], c[1]) for c in cases))} options: "
          f"{outcomes.count('ran')} ran, {outcomes.count('refused')} refused with a message, {len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
