#!/usr/bin/env python3
"""Fits the localizer's confidence value and judges its flag, from per-scan traces.

    scripts/confidence_fit.py TRACE_DIR [--train fr079,intel] [--up P] [--hold P]
                              [--weights W0,W1,...] [--diagram OUT.csv]
                              [--unmapped DIR] [--unmapped-share S] [--flag-threshold T]

TRACE_DIR holds `lshloc eval --trace` CSVs (scripts/sweep.sh with TRACE_DIR=...),
named after their arguments (the building follows "--building"). The value is
a logistic model of the report's evidence (ConfidenceConfig::weights, in the
order of FEATURES), fitted by Newton's method on the training buildings'
judged scans only (every scan with a measured or interpolated truth, or estimated in another submap), each
building weighing the same; a scan is right when its estimate is in the true submap within 2 m and 10 degrees
of a measured truth (45 degrees of an interpolated one). Prints the weights, the expected calibration
error (10 equal-width bins) per building and overall, and the flag's figures
(rises at --up, held while the place is kept and the value stays >= --hold)
as the acceptance check counts them; --flag evidence replays the localizer's
own flag rule from the evidence columns instead, with its parameters as
options (how they were chosen: docs/results/confidence.md). With --weights,
judges those instead of fitting. --diagram writes the reliability diagram's bins (all buildings).

--unmapped DIR holds `lshloc localize --out` CSVs named BUILDING.tum.csv of a
building's log localized in a map without that building
(scripts/unmapped_buildings.sh): every estimate there is wrong. Those of the
training buildings join the fit as negatives, together weighing
--unmapped-share of it (the share of scans a robot takes where the map does
not reach); every one is reported with its mean value, which a calibrated
value keeps near 0. The value judged is the localizer's: raised to
--flag-threshold where the trace's flag is up, held under it elsewhere.
"""
import argparse
import csv
import glob
import math
import os
import re
import statistics

FEATURES = ["bias", "mean_score", "margin", "log_scored", "log_kept", "place_supported", "stable", "supported",
            "newest_fit", "newest_evidence"]


def features(r):
    return [1.0, float(r["mean_score"]), float(r["margin"]), math.log1p(float(r["scored"])),
            math.log1p(float(r["kept_scans"])), float(r["place_supported"]), float(r["stable"]),
            float(r["supported"]), float(r["newest_fit"]), float(r["newest_evidence"])]


def load(trace_dir):
    runs = []
    for path in sorted(glob.glob(os.path.join(trace_dir, "*.csv"))):
        if path.endswith(".truth.csv"):
            continue
        m = re.search(r"building_([A-Za-z0-9-]+)_", os.path.basename(path))
        building = m.group(1) if m else os.path.basename(path).split("_")[0]
        scans = []
        with open(path) as f:
            for r in csv.DictReader(f):
                has = r["has_estimate"] == "1"
                # Every judged scan's errors (judged_*); older traces have them at truth scans only.
                e_col, h_col = ("judged_error_m", "judged_heading_error_deg") if "judged_error_m" in r else \
                    ("error_m", "heading_error_deg")
                truth = r[e_col] != ""
                err = float(r[e_col]) if truth else math.nan
                head = float(r[h_col]) if truth and r[h_col] != "" else math.nan
                # Between truth scans the heading is judged to 45 degrees (docs/design.md section 6).
                head_limit = 45.0 if r.get("interpolated_x") else 10.0
                # rise_margin: the margin the rise read (a rival dropped within
                # rival_memory_scans still stands); traces before it have margin only.
                scans.append({"lead": float(r.get("whole_map_lead") or 0.0) if has else 0.0,
                              "rise_margin": float(r.get("rise_margin") or r["margin"]) if has else 0.0,
                              # the rival behind rise_margin and its N (traces before it: none)
                              "rival_scored": float(r["rival_scored"]) if has and r.get("rival_scored") else None,
                              "newest_lead": float(r.get("newest_lead") or "nan") if has else math.nan,
                              "x": features(r) if has else None, "truth": truth, "err": err,
                              "flag": r["localized"] == "1",
                              "right": truth and has and err <= 2.0 and head <= head_limit,
                              "correct": truth and has and err < 1.0})
        runs.append((building, path, scans))
    return runs


def load_unmapped(directory):
    """{building: scans} from `localize --out` CSVs of buildings the map lacks (all estimates wrong)."""
    out = {}
    for path in sorted(glob.glob(os.path.join(directory, "*.tum.csv"))):
        scans = []
        with open(path) as f:
            for r in csv.DictReader(f):
                if r["score"] == "":
                    continue  # no estimate
                r = dict(r, mean_score=r["score"])
                scans.append({"x": features(r), "flag": r["localized"] == "1"})
        out[os.path.basename(path)[:-len(".tum.csv")]] = scans
    return out


def reported(p, flag, threshold):
    """The localizer's value: the flag decides the side of the threshold (ConfidenceConfig::flag_threshold);
    a threshold above 1 leaves the model's value as it is."""
    if threshold > 1.0:
        return p
    return max(p, threshold) if flag else min(p, threshold - 0.001)


def sigmoid(z):
    return 1.0 / (1.0 + math.exp(-z)) if z > -500 else 0.0


def value(w, x):
    return 0.0 if x is None else sigmoid(sum(a * b for a, b in zip(w, x)))


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


def fit(rows, ridge=1e-3, iterations=25):
    """Weighted logistic regression by Newton's method, a small ridge for
    separable data. rows: (features, label, weight)."""
    k = len(FEATURES)
    w = [0.0] * k
    for _ in range(iterations):
        grad = [0.0] * k
        hess = [[ridge if i == j else 0.0 for j in range(k)] for i in range(k)]
        for x, y, c in rows:
            p = value(w, x)
            g = c * (p - y)
            s = c * p * (1.0 - p)
            for i in range(k):
                grad[i] += g * x[i]
                xi = s * x[i]
                row = hess[i]
                for j in range(i + 1):
                    row[j] += xi * x[j]
        for i in range(k):
            grad[i] += ridge * w[i]
            for j in range(i):
                hess[j][i] = hess[i][j]
        step = solve(hess, grad)
        w = [a - b for a, b in zip(w, step)]
        if max(abs(s) for s in step) < 1e-6:
            break
    return w


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


def value_flag(w, up, hold):
    """The flag as the value above `up`, held while the place is kept and the value stays >= `hold`."""
    def rule(s, flag, state):
        p = value(w, s["x"])
        kept = s["x"] is not None and s["x"][4] > 0.0
        return p >= up or (flag and kept and p >= hold)
    return rule


def evidence_flag(rise_fit, hold_penalty, hold_mean_penalty, smoothing, min_margin=0.15, supported_scans=3,
                  unsupported_hold=20, rise_lead=math.inf, weak_support=None, scored_per_kept_scan=12.5,
                  max_scored=750, rival_min_scored=250, paired_lead=(0.15, 0.25), relative_support=None,
                  young_rival_lead=math.inf, extra_support=None):
    """The localizer's flag (ConfidenceConfig: rise_min_newest_fit, hold_max_contradiction,
    hold_max_mean_contradiction, contradiction_smoothing, rise_supported_scans, unsupported_hold_scans,
    rise_margin_whole_map_lead, rise_paired_whole_map_lead and rise_paired_newest_lead (paired_lead),
    rise_scored_per_kept_scan, rise_max_scored, rise_rival_min_scored;
    rival_memory_scans and rival_twin_turn_deg through the trace's rise_margin) replayed from a trace's evidence columns (a trace scores the whole-map
    lead on every scan). weak_support (ConfidenceConfig::weak_support, weak_support_min_mean_score,
    _min_scored, _min_margin, _min_whole_map_lead, silent_newest_evidence, weak_support_max_newest_evidence;
    None: off): (C/N, N, margin, whole-map lead, silent evidence[, max newest evidence]): a scan meeting
    the first four (and the last, where given: the map scores at most that share of the newest points)
    also counts as supported (and makes its place supported), and a rise passes the newest-fit test when
    the map scores at most the silent evidence's share of the newest points. relative_support
    (ConfidenceConfig::relative_support_min_mean_score, _min_scored, _min_margin, _min_whole_map_lead;
    None: off): (C/N, N, margin, whole-map lead, newest lead): a scan meeting all five, over a rival scored
    on rival_min_scored or more, counts as weak support does.
    young_rival_lead (rise_young_rival_whole_map_lead): the whole-map lead that passes the margin over a
    rival scored on fewer than rival_min_scored (rise_lead over any other).
    extra_support (what-if, no ConfidenceConfig field; None: off): (C/N, N, margin, whole-map lead): a scan
    meeting all four also counts as weak support does."""
    def rule(s, flag, state):
        x = s["x"]
        if x is None:
            state.clear()
            return False
        margin, place_supported, stable, supported, fit, evidence = s["rise_margin"], x[5], x[6], x[7], x[8], x[9]
        kept_scans = round(math.expm1(x[4]))
        kept = kept_scans > 0
        if not kept:
            state["qualified"] = False
            state["weak_place"] = False
        weak = weak_support is not None and (x[1] >= weak_support[0] and round(math.expm1(x[3])) >= weak_support[1]
                                             and margin >= weak_support[2] and s["lead"] >= weak_support[3]
                                             and (len(weak_support) < 6 or x[9] <= weak_support[5]))
        weak = weak or (relative_support is not None and x[1] >= relative_support[0]
                        and round(math.expm1(x[3])) >= relative_support[1] and margin >= relative_support[2]
                        and s["lead"] >= relative_support[3] and s["newest_lead"] >= relative_support[4]
                        and (s["rival_scored"] is None or s["rival_scored"] >= rival_min_scored))
        weak = weak or (extra_support is not None and x[1] >= extra_support[0]
                        and round(math.expm1(x[3])) >= extra_support[1] and margin >= extra_support[2]
                        and s["lead"] >= extra_support[3])
        if weak and kept:
            state["weak_place"] = True
        place_supported = place_supported > 0 or state.get("weak_place", False)
        supported = supported > 0 or weak
        fit_passes = fit >= rise_fit or (weak_support is not None and evidence <= weak_support[4])
        if supported:
            if state.get("run", 0) == 0:
                long_unsupported = kept_scans >= unsupported_hold and not state.get("qualified", False)
                state["needs"] = supported_scans if long_unsupported else 1
            state["run"] = state.get("run", 0) + 1
            state["qualified"] = state.get("qualified", False) or state["run"] >= state["needs"]
        else:
            state["run"] = 0
        penalty = 0.5 * (evidence - fit)
        state["mean"] = (1 - smoothing) * state.get("mean", 0.0) + smoothing * penalty if flag else penalty
        # rise_rival_min_scored: over a rival scored on few points the margin needs the whole-map lead too,
        # and a lead alone must reach rise_young_rival_whole_map_lead
        young = s["rival_scored"] is not None and s["rival_scored"] < rival_min_scored
        if young:
            margin = min(margin, s["lead"])
        # rise_scored_per_kept_scan, rise_max_scored: a new hypothesis at a long-kept place waits
        seasoned = round(math.expm1(x[3])) >= min(scored_per_kept_scan * kept_scans, max_scored) - 1e-6
        # rise_paired_*: a whole-map lead paired with a lead on the newest points, over a rival scored on
        # rise_rival_min_scored or more (traces before it: NaN, never)
        paired = (s["lead"] >= paired_lead[0] and s["newest_lead"] >= paired_lead[1]
                  and (s["rival_scored"] is None or s["rival_scored"] >= rival_min_scored))
        rises = (stable > 0 and supported and state["run"] >= state["needs"]
                 and (margin >= min_margin or s["lead"] >= (young_rival_lead if young else rise_lead) or paired)
                 and fit_passes and seasoned)
        held = flag and kept and place_supported and penalty <= hold_penalty and state["mean"] <= hold_mean_penalty
        return rises or held
    return rule


def judge_run(scans, rule):
    """The flag over one run and the acceptance check's per-run figures (as `eval` counts them)."""
    flag, changes, first, wrong = False, 0, None, 0
    flags = []
    state = {}
    for i, s in enumerate(scans):
        new = rule(s, flag, state)
        changes += new != flag
        flag = new
        flags.append(flag)
        if flag and first is None:
            first = i
        if flag and s["truth"] and not s["right"]:
            wrong += 1
    truth_idx = [i for i, s in enumerate(scans) if s["truth"]]
    last_bad = None
    for i in truth_idx:
        if not scans[i]["correct"]:
            last_bad = i
    localized_at = None
    if truth_idx and last_bad != truth_idx[-1]:
        # eval's localized_at: the first ground-truth scan after the last incorrect one.
        localized_at = truth_idx[0] if last_bad is None else next(i for i in truth_idx if i > last_bad)
    share = None
    if localized_at is not None:
        after = [i for i in truth_idx if i >= localized_at]
        share = sum(flags[i] for i in after) / len(after)
    success = bool(truth_idx) and scans[truth_idx[-1]]["correct"]
    return {"success": success, "localized_at": localized_at, "first": first, "share": share, "changes": changes,
            "wrong": wrong, "truth": len(truth_idx)}


def summary(name, results):
    succ = [r for r in results if r["success"]]
    shares = [r["share"] for r in succ if r["share"] is not None]
    lags = [(r["first"] - r["localized_at"]) if r["first"] is not None else 10**6 for r in succ]
    wrong = sum(r["wrong"] for r in results)
    truth = sum(r["truth"] for r in results)
    half = sum(1 for v in shares if v >= 0.5)
    print(f"{name}: {len(succ)}/{len(results)} succeed; share after median "
          f"{statistics.median(shares) if shares else float('nan'):.3f}, >= 0.5 in {half}/{len(shares)}; "
          f"lag median {statistics.median(lags) if lags else float('nan')}; flag changes median "
          f"{statistics.median([r['changes'] for r in succ]) if succ else float('nan')}; "
          f"confident-but-wrong {wrong} of {truth}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("trace_dir")
    ap.add_argument("--train", default="fr079,intel")
    ap.add_argument("--up", type=float, default=0.9)
    ap.add_argument("--hold", type=float, default=0.5)
    ap.add_argument("--weights")
    ap.add_argument("--diagram")
    ap.add_argument("--flag", choices=["value", "evidence"], default="value",
                    help="the flag judged: the value above --up, held at --hold (value), or the localizer's rule "
                         "from the evidence columns with --rise-fit, --hold-penalty, --hold-mean-penalty, --smoothing, "
                         "--rise-supported-scans, --unsupported-hold-scans")
    ap.add_argument("--rise-fit", type=float, default=0.1)
    ap.add_argument("--hold-penalty", type=float, default=0.13)
    ap.add_argument("--hold-mean-penalty", type=float, default=0.1)
    ap.add_argument("--smoothing", type=float, default=0.3)
    ap.add_argument("--rise-supported-scans", type=int, default=3)
    ap.add_argument("--unsupported-hold-scans", type=int, default=20)
    ap.add_argument("--rise-lead", type=float, default=0.2,
                    help="the whole-map lead that also passes the rise's margin test (inf: off)")
    ap.add_argument("--young-rival-lead", type=float, default=0.25,
                    help="... over a rival scored on fewer than --rival-min-scored (rise_young_rival_whole_map_lead)")
    ap.add_argument("--relative-support", default="0.25,300,0.05,0.2,0.1",
                    help="C/N,N,MARGIN,LEAD,NEWEST_LEAD: the relative support test (ConfidenceConfig::relative_support_*; "
                    "'off': without it)")
    ap.add_argument("--extra-support",
                    help="C/N,N,MARGIN,LEAD: what if a scan meeting these also counted as supported (a test the "
                         "localizer does not have; default: off)")
    ap.add_argument("--paired-lead", default="0.15,0.25",
                    help="WHOLE,NEWEST: the whole-map lead and the lead on the newest points that together pass the "
                         "margin (rise_paired_whole_map_lead, rise_paired_newest_lead; 9,9: off)")
    ap.add_argument("--rival-min-scored", type=float, default=250,
                    help="below this N a rival's margin also needs the whole-map lead (rise_rival_min_scored; 0: off)")
    ap.add_argument("--unmapped", help="directory of localize CSVs in buildings the map lacks (BUILDING.tum.csv)")
    ap.add_argument("--unmapped-share", type=float, default=0.1,
                    help="the training weight of the training buildings' unmapped runs, as a share of the whole")
    ap.add_argument("--flag-threshold", type=float, default=0.95,
                    help="ConfidenceConfig::flag_threshold (the flag lifts the value to it; > 1: the raw model)")
    ap.add_argument("--weak-support", default="0.2,3000,0.2,0.15,0.05,0.2",
                    help="C/N,N,MARGIN,LEAD,SILENT,EVIDENCE: the weak support test (ConfidenceConfig::weak_support_*, "
                    "silent_newest_evidence; 'off': without it)")
    a = ap.parse_args()
    runs = load(a.trace_dir)
    unmapped = load_unmapped(a.unmapped) if a.unmapped else {}
    train = set(a.train.split(","))
    if a.weights:
        w = [float(v) for v in a.weights.split(",")]
    else:
        # Each training building weighs the same, however many ground-truth
        # scans its windows hold (fr079 has ~40x intel's).
        rows = {b: [(s["x"], 1.0 if s["right"] else 0.0) for bb, _, scans in runs if bb == b for s in scans
                    if s["truth"] and s["x"] is not None] for b in train}
        weighted = [(x, y, 1.0 / (len(rows) * len(r))) for r in rows.values() for x, y in r]
        negatives = {b: v for b, v in unmapped.items() if b in train and v}
        if negatives:
            # The buildings' own scans keep 1 - share, the unmapped runs share the rest equally.
            share = a.unmapped_share
            weighted = [(x, y, c * (1.0 - share)) for x, y, c in weighted]
            weighted += [(s["x"], 0.0, share / (len(negatives) * len(v))) for v in negatives.values() for s in v]
        total = sum(len(r) for r in rows.values()) + sum(len(v) for v in negatives.values())
        w = fit([(x, y, c * total) for x, y, c in weighted])
    print("weights (" + ", ".join(FEATURES) + "): " + ",".join(f"{v:.4f}" for v in w))
    flag_rule = (value_flag(w, a.up, a.hold) if a.flag == "value" else
                 evidence_flag(a.rise_fit, a.hold_penalty, a.hold_mean_penalty, a.smoothing,
                               supported_scans=a.rise_supported_scans, unsupported_hold=a.unsupported_hold_scans,
                               rise_lead=a.rise_lead, rival_min_scored=a.rival_min_scored,
                               young_rival_lead=a.young_rival_lead,
                               extra_support=[float(v) for v in a.extra_support.split(",")] if a.extra_support else None,
                               relative_support=None if a.relative_support == "off" else
                               [float(v) for v in a.relative_support.split(",")],
                               paired_lead=tuple(float(v) for v in a.paired_lead.split(",")),
                               weak_support=None if a.weak_support == "off" else [float(v) for v in a.weak_support.split(",")]))
    buildings = sorted({b for b, _, _ in runs})
    everything = []
    for b in buildings:
        pairs = [(reported(value(w, s["x"]), s["flag"], a.flag_threshold), 1.0 if s["right"] else 0.0)
                 for bb, _, scans in runs if bb == b for s in scans if s["truth"]]
        everything += pairs
        e, _ = ece(pairs)
        results = [judge_run(scans, flag_rule) for bb, _, scans in runs if bb == b]
        summary(f"{b} ({'train' if b in train else 'unseen'}, ECE {e:.4f})", results)
    e, table = ece(everything)
    summary(f"all (ECE {e:.4f})", [judge_run(scans, flag_rule) for _, _, scans in runs])
    for b, scans in unmapped.items():
        values = [reported(value(w, s["x"]), s["flag"], a.flag_threshold) for s in scans]
        print(f"{b} unmapped ({'train' if b in train else 'unseen'}): {len(values)} estimates, all wrong; "
              f"mean value {statistics.mean(values) if values else float('nan'):.3f}, flagged "
              f"{sum(s['flag'] for s in scans)}")
    if a.diagram:
        with open(a.diagram, "w") as f:
            f.write("lo,hi,count,mean_value,share_right\n")
            for row in table:
                f.write(",".join(f"{v:.6g}" for v in row) + "\n")


if __name__ == "__main__":
    main()
