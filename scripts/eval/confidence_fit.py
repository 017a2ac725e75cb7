#!/usr/bin/env python3
"""Fits the localizer's confidence value from per-scan traces and writes its weights.

    scripts/eval/confidence_fit.py --train DIR[,DIR...] [--judge NAME=DIR[,DIR...] ...]
                              [--outside DIR] [--outside-share S] [--write JSON] [--diagram OUT.csv]

The value is P(the estimate is right) = 1 / (1 + exp(-w . f)) over the features that
src/localization/confidence_value.json names (read from there, so the vector is written once), with one
weight vector while the flag is down and one while it is up. Each is fitted by logistic regression
(Newton's method, a small ridge) on the judged scans of the --train traces (`lshloc eval --trace`
CSVs, e.g. scripts/eval/sweep.sh with TRACE_DIR): every scan with a measured or interpolated truth, or
estimated in another submap; right when in the true submap within 2 m and 10 degrees of a measured
truth (45 degrees of an interpolated one), as `lshloc calibration` judges. The flag is the trace's
own (`localized`): the value does not decide it.

--outside DIR: `lshloc localize --out` CSVs (*.tum.csv) of robots where the map does not hold them
(every estimate wrong) join the flag-down fit as negatives weighing --outside-share of it.
Prints the weights and the expected calibration error (10 equal-width bins) of the reported value
(raised to the flag threshold where the flag is up, held under it elsewhere) for the training set and
every --judge set. --write JSON: the weights into that file (the library's
src/localization/confidence_value.json), with the command that fitted them.
"""
import argparse
import csv
import glob
import json
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
VALUE_JSON = os.path.join(HERE, "..", "..", "src", "localization", "confidence_value.json")
# The value's features name the localizer's C/N `mean_score`; the estimate schema's column is `score`
# (traces written before the one schema have `mean_score`).
ALIASES = {"mean_score": "score"}


def feature_of(name):
    """A feature named in confidence_value.json, from a CSV row: "bias", a column, or "log1p:COLUMN"."""
    if name == "bias":
        return lambda r: 1.0
    column = name.split(":", 1)[-1]
    transform = math.log1p if name.startswith("log1p:") else float

    def get(r):
        value = r.get(column)
        if value is None:
            value = r[ALIASES[column]]
        return transform(float(value))
    return get


def judged_scans(path, features):
    """(features, right, flag) of every judged scan of an eval trace."""
    out = []
    with open(path) as f:
        for r in csv.DictReader(f):
            if r["submap"] == "" or r["judged_error_m"] == "":
                continue
            err = float(r["judged_error_m"])
            head = float(r["judged_heading_error_deg"]) if r["judged_heading_error_deg"] != "" else 0.0
            limit = 45.0 if r["interpolated_x"] else 10.0
            out.append(([g(r) for g in features], 1.0 if err <= 2.0 and head <= limit else 0.0, r["localized"] == "1"))
    return out


def outside_scans(directory, features):
    out = []
    for path in sorted(glob.glob(os.path.join(directory, "*.tum.csv"))):
        with open(path) as f:
            for r in csv.DictReader(f):
                if r["x"] != "":
                    out.append(([g(r) for g in features], 0.0, r["localized"] == "1"))
    return out


def traces(dirs):
    paths = []
    for d in dirs.split(","):
        paths += [p for p in sorted(glob.glob(os.path.join(d, "*.csv"))) if not p.endswith(".truth.csv")]
    if not paths:
        sys.exit(f"confidence_fit: no traces in {dirs}")
    return paths


def sigmoid(z):
    return 1.0 / (1.0 + math.exp(-max(-500.0, min(500.0, z))))


def fit(rows, k, ridge=1e-3, iterations=30):
    """Weighted logistic regression by Newton's method; rows: (features, label, weight)."""
    w = [0.0] * k
    for _ in range(iterations):
        grad = [ridge * v for v in w]
        hess = [[ridge if i == j else 0.0 for j in range(k)] for i in range(k)]
        for x, y, c in rows:
            p = sigmoid(sum(a * b for a, b in zip(w, x)))
            for i in range(k):
                grad[i] += c * (p - y) * x[i]
                for j in range(i, k):
                    hess[i][j] += c * p * (1.0 - p) * x[i] * x[j]
        for i in range(k):
            for j in range(i):
                hess[i][j] = hess[j][i]
        step = solve(hess, grad)
        w = [a - b for a, b in zip(w, step)]
        if max(abs(s) for s in step) < 1e-7:
            break
    return w


def solve(a, b):
    """Gaussian elimination with partial pivoting: a x = b."""
    n = len(b)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for c in range(n):
        p = max(range(c, n), key=lambda i: abs(m[i][c]))
        m[c], m[p] = m[p], m[c]
        for i in range(c + 1, n):
            f = m[i][c] / m[c][c]
            for j in range(c, n + 1):
                m[i][j] -= f * m[c][j]
    x = [0.0] * n
    for i in reversed(range(n)):
        x[i] = (m[i][n] - sum(m[i][j] * x[j] for j in range(i + 1, n))) / m[i][i]
    return x


def reported(weights, x, flag, threshold):
    """The localizer's value: the flag's weights, then the flag decides the side of the threshold."""
    p = sigmoid(sum(a * b for a, b in zip(weights[flag], x)))
    return max(p, threshold) if flag else min(p, threshold - 0.001)


def ece(pairs, bins=10):
    """Expected calibration error and the diagram's bins: (lo, hi, count, mean value, share right)."""
    table = [[0, 0.0, 0.0] for _ in range(bins)]
    for p, y in pairs:
        b = min(int(p * bins), bins - 1)
        table[b][0] += 1
        table[b][1] += p
        table[b][2] += y
    n = len(pairs)
    e = sum(abs(c[1] - c[2]) for c in table if c[0]) / n if n else math.nan
    return e, [(i / bins, (i + 1) / bins, c[0], c[1] / c[0] if c[0] else math.nan, c[2] / c[0] if c[0] else math.nan)
               for i, c in enumerate(table)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--train", required=True, help="directories of eval traces to fit on, comma-separated")
    ap.add_argument("--judge", action="append", default=[], help="NAME=DIRS: another set to report the ECE of")
    ap.add_argument("--outside", help="directory of localize CSVs where the map does not hold the robot")
    ap.add_argument("--outside-share", type=float, default=0.1)
    ap.add_argument("--flag-threshold", type=float, default=0.9, help="ConfidenceConfig::flag_threshold")
    ap.add_argument("--write", help="write the weights into this JSON file (the library's confidence_value.json)")
    ap.add_argument("--diagram", help="write the training set's reliability diagram (CSV)")
    a = ap.parse_args()
    with open(VALUE_JSON) as f:
        spec = json.load(f)
    names = spec["features"]
    features = [feature_of(n) for n in names]
    train = [s for p in traces(a.train) for s in judged_scans(p, features)]
    weights = {}
    for flag in (False, True):
        rows = [(x, y, 1.0) for x, y, fl in train if fl == flag]
        if not flag and a.outside:
            outside = [s for s in outside_scans(a.outside, features) if not s[2]]
            if outside:
                c = a.outside_share * len(rows) / ((1.0 - a.outside_share) * len(outside))
                rows += [(x, 0.0, c) for x, _, _ in outside]
        # The flag-up scans are nearly all right: a stronger ridge keeps their weights finite.
        weights[flag] = fit(rows, len(names), ridge=1.0 if flag else 1e-3)
        print(f"flag {'up' if flag else 'down'}: {len(rows)} scans, weights " +
              ",".join(f"{v:.4f}" for v in weights[flag]))
    sets = [("train", train)] + [(j.split("=", 1)[0], [s for p in traces(j.split("=", 1)[1])
                                                      for s in judged_scans(p, features)]) for j in a.judge]
    for name, scans in sets:
        e, _ = ece([(reported(weights, x, fl, a.flag_threshold), y) for x, y, fl in scans])
        print(f"{name}: ECE {e:.4f} over {len(scans)} judged scans")
    if a.diagram:
        _, table = ece([(reported(weights, x, fl, a.flag_threshold), y) for x, y, fl in train])
        with open(a.diagram, "w") as f:
            f.write("lo,hi,count,mean_value,share_right\n")
            for row in table:
                f.write(",".join(f"{v:.6g}" for v in row) + "\n")
    if a.write:
        spec["flag_down"] = [round(v, 4) for v in weights[False]]
        spec["flag_up"] = [round(v, 4) for v in weights[True]]
        spec["fitted_by"] = "scripts/eval/confidence_fit.py " + " ".join(sys.argv[1:])
        with open(a.write, "w") as f:
            json.dump(spec, f, indent=2)
            f.write("\n")


if __name__ == "__main__":
    main()
