#!/usr/bin/env python3
"""scripts/eval/confidence_fit.py on synthetic traces whose labels follow a known logistic model: the fitted
flag-down weights recover it, the reported value is calibrated, and --write keeps the library's feature
names and records the command. Usage: confidence_fit_test.py SOURCE_DIR"""
import csv, json, math, os, random, subprocess, sys, tempfile

src = sys.argv[1]
script = os.path.join(src, "scripts", "eval", "confidence_fit.py")
spec = json.load(open(os.path.join(src, "src", "localization", "confidence_value.json")))
d = tempfile.mkdtemp()
rng = random.Random(7)
# The truth: while the flag is down, P(right) = sigmoid(-2 + 6 C/N + 3 newest_fit); up, right 99%.
true_down = {"bias": -2.0, "mean_score": 6.0, "newest_fit": 3.0}
cols = ["scan", "submap", "localized", "score", "margin", "scored", "kept_scans", "place_supported",
        "stable", "supported", "newest_fit", "newest_evidence", "judged_error_m", "judged_heading_error_deg",
        "interpolated_x"]
for run in range(4):
    with open(os.path.join(d, f"run{run}.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for i in range(6000):
            up = rng.random() < 0.3
            cn, nf = rng.uniform(-0.2, 0.8), rng.uniform(-0.5, 0.8)
            p = 0.99 if up else 1 / (1 + math.exp(-(-2.0 + 6.0 * cn + 3.0 * nf)))
            right = rng.random() < p
            # Every other scan between truth scans (interpolated): wrong there beyond 2 m, like at truth.
            w.writerow([i, "hall", int(up), cn, rng.uniform(0, 0.3), rng.randint(0, 5000), rng.randint(0, 100),
                        rng.randint(0, 1), rng.randint(0, 1), rng.randint(0, 1), nf, rng.uniform(0, 1),
                        0.1 if right else 5.0, 1.0, "1.0" if i % 2 else ""])
        w.writerow([6000, "", 0] + [""] * (len(cols) - 3))  # no estimate: not judged
out = os.path.join(d, "value.json")
r = subprocess.run([sys.executable, script, "--train", d, "--write", out], capture_output=True, text=True)
assert r.returncode == 0, r.stderr
written = json.load(open(out))
assert written["features"] == spec["features"], written["features"]
assert written["fitted_by"].startswith("scripts/eval/confidence_fit.py --train "), written["fitted_by"]
down = dict(zip(written["features"], written["flag_down"]))
for name, value in down.items():
    want = true_down.get(name, 0.0)
    assert abs(value - want) < 0.35, (name, value, want)
ece = float(r.stdout.split("train: ECE ")[1].split()[0])
assert ece < 0.02, r.stdout
# A directory without traces is an error that names it.
empty = tempfile.mkdtemp()
r = subprocess.run([sys.executable, script, "--train", empty], capture_output=True, text=True)
assert r.returncode != 0 and empty in r.stderr, r.stderr
print("confidence_fit: ok", {k: round(v, 2) for k, v in down.items()}, "ECE", ece)
