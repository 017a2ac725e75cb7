#!/usr/bin/env python3
"""Markdown tables of the sweep's JSON lines (scripts/eval/sweep.sh): results/*.jsonl -> stdout."""
import json
import statistics
import sys
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent.parent  # git history lives there, wherever results/ is


def load(name):
    path = Path("results") / f"{name}.jsonl"
    if not path.exists():
        return []
    rows = [json.loads(l) for l in path.read_text().splitlines() if l.strip()]
    return [r for r in rows if "failed" not in r]


def fmt(v, digits=3):
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def judged(r):
    """Judged / scans: how much of the window the figures see (every scan with a measured or interpolated truth)."""
    return f"{r['judged_scans']} / {r['length']}" if "judged_scans" in r else "—"


def wrong_dense(r):
    """Confident scans judged, and of them wrong: on every judged scan (at ground-truth scans only)."""
    if "confident_judged" not in r:  # a line from before every scan was judged
        return f"— / {r['confident_wrong']} (at truth)"
    return f"{r['confident_judged']} / {r['confident_wrong']} ({r['confident_wrong_at_truth']})"


def wrong_total(rows):
    conf = sum(r.get("confident_judged", 0) for r in rows)
    wrong = sum(r["confident_wrong"] for r in rows)
    at_truth = sum(r.get("confident_wrong_at_truth", r["confident_wrong"]) for r in rows)
    return conf, wrong, at_truth


def grid():
    rows = load("grid")
    if not rows:
        return
    print("| building | R | map features | success | final error [m] | heading err [deg] | localized at | median error after [m] | CPU s to localize | judged / scans | confident judged / wrong (at truth scans) | ms/scan | x real time |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in sorted(rows, key=lambda r: (r["building"], r["submaps"])):
        print(f"| {r['building']} | {r['submaps']} | {r['map_features']} | {fmt(r['success'])} | {fmt(r['final_error_m'])} | "
              f"{fmt(r['final_heading_error_deg'], 2)} | {fmt(r['localized_at'])} | {fmt(r['median_error_after_m'])} | "
              f"{fmt(r['cpu_s_to_localize'], 2)} | {judged(r)} | {wrong_dense(r)} | {fmt(r['ms_per_scan'], 2)} | "
              f"{fmt(r['realtime_factor'], 0)} |")
    ok = sum(r["success"] for r in rows)
    errs = [r["final_error_m"] for r in rows if r["final_error_m"] is not None]
    print(f"\n{ok}/{len(rows)} scenarios succeed; median final error {statistics.median(errs):.3f} m" if errs else "")
    conf, wrong, at_truth = wrong_total(rows)
    print(f"; confident estimates judged: {conf}, wrong: {wrong} (counted at ground-truth scans only: {at_truth}).\n")


def beside_batch(rows):
    """Each row, in scenario order, with the batch run of the same scenario (results/grid.jsonl; {} if none)."""
    batch = {(r["building"], r["submaps"]): r for r in load("grid")}
    ordered = sorted(rows, key=lambda r: (r["building"], r["submaps"]))
    return [(r, batch.get((r["building"], r["submaps"]), {})) for r in ordered]


def grid_maps():
    """The 16 scenarios with every submap rebuilt from its occupancy grid, beside the log-built maps."""
    rows = load("grid_maps")
    if not rows:
        return
    print("| building | R | map features: grid / logs | success: grid / logs | final error [m]: grid / logs | "
          "localized at: grid / logs | median error after [m]: grid / logs | confident scans: grid / logs | "
          "map build s (grid) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r, l in beside_batch(rows):
        pair = lambda k, d=3: f"{fmt(r.get(k), d)} / {fmt(l.get(k), d)}"
        print(f"| {r['building']} | {r['submaps']} | {pair('map_features')} | {pair('success')} | "
              f"{pair('final_error_m')} | {pair('localized_at')} | {pair('median_error_after_m')} | "
              f"{pair('confident_scans')} | {fmt(r['map_build_s'], 1)} |")
    ok = sum(r["success"] for r in rows)
    errs = [r["final_error_m"] for r in rows if r["final_error_m"] is not None]
    wrong = sum(r["confident_wrong"] for r in rows)
    print(f"\n{ok}/{len(rows)} scenarios succeed with grid-built maps; median final error "
          f"{statistics.median(errs):.3f} m; confident but wrong: {wrong}.\n")


def live():
    """The 16 scenarios live (eval --live) beside the batch ones (results/grid.jsonl)."""
    rows = load("live")
    if not rows:
        return
    print("| building | R | success: live / batch | first mapped at | localized at: live / batch | "
          "mapped to localized | confident but wrong: before mapped / after | final place mapped | "
          "mapper scans/s | ms/scan p99 |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r, b in beside_batch(rows):
        print(f"| {r['building']} | {r['submaps']} | {fmt(r['success'])} / {fmt(b.get('success'))} | "
              f"{fmt(r['first_mapped_at'])} | {fmt(r['localized_at'])} / {fmt(b.get('localized_at'))} | "
              f"{fmt(r['mapped_to_localized'])} | {r['confident_wrong_before_mapped']} / "
              f"{r['confident_wrong_after_mapped']} | {fmt(r['final_place_mapped'])} | "
              f"{fmt(r['map_scans_per_s'], 0)} | {fmt(r['ms_per_scan_p99'], 2)} |")
    ok = sum(r["success"] for r in rows)
    m2l = [r["mapped_to_localized"] for r in rows if r["mapped_to_localized"] is not None]
    before = sum(r["confident_wrong_before_mapped"] for r in rows)
    conf, wrong, at_truth = wrong_total(rows)
    print(f"\n{ok}/{len(rows)} live scenarios succeed; median mapped_to_localized "
          f"{fmt(statistics.median(m2l) if m2l else None, 1)} scans; confident but wrong {wrong} of {conf} "
          f"judged confident scans ({at_truth} at ground-truth scans), {before} before the place was mapped.\n")


def live_starts():
    """The 80 starts live; runs whose final true pose was never mapped are reported apart."""
    rows = load("live_starts")
    if not rows:
        return
    print("| building (R = 15, live) | starts | final place mapped | succeeding among those | "
          "succeeding, the others | median mapped to localized | confident but wrong: before mapped / all |")
    print("|---|---|---|---|---|---|---|")
    groups = sorted(by(rows, lambda r: r["building"]).items()) + [("all", rows)]
    for b, rs in groups:
        mapped = [r for r in rs if r.get("final_place_mapped")]
        other = [r for r in rs if not r.get("final_place_mapped")]
        m2l = [r["mapped_to_localized"] for r in rs if r.get("mapped_to_localized") is not None]
        print(f"| {b} | {len(rs)} | {len(mapped)} | {sum(r['success'] for r in mapped)}/{len(mapped)} | "
              f"{sum(r['success'] for r in other)}/{len(other)} | "
              f"{fmt(statistics.median(m2l) if m2l else None, 1)} | "
              f"{sum(r['confident_wrong_before_mapped'] for r in rs)} / {sum(r['confident_wrong'] for r in rs)} |")
    print()


def by(rows, key):
    groups = defaultdict(list)
    for r in rows:
        groups[key(r)].append(r)
    return groups


def summary_line(rs):
    ok = sum(r["success"] for r in rs)
    at = sorted(r["localized_at"] for r in rs if r["success"] and r["localized_at"] is not None)
    med = [r["median_error_after_m"] for r in rs if r["median_error_after_m"] is not None]
    conf, wrong, at_truth = wrong_total(rs)
    return (f"{ok}/{len(rs)} | {fmt(statistics.median(at) if at else None, 1)} | "
            f"{fmt(statistics.median(med) if med else None)} | {conf} / {wrong} ({at_truth})")


def orders():
    rows = load("orders")
    if not rows:
        return
    print("| building (R = 4) | order rule | success | final error [m] | localized at | median error after [m] | ms/scan |")
    print("|---|---|---|---|---|---|---|")
    for r in sorted(rows, key=lambda r: (r["building"], r.get("order_rule", ""))):
        print(f"| {r['building']} | {r.get('order_rule')} | {fmt(r['success'])} | {fmt(r['final_error_m'])} | "
              f"{fmt(r['localized_at'])} | {fmt(r['median_error_after_m'])} | {fmt(r['ms_per_scan'], 2)} |")
    print()


def ablation():
    rows = load("ablation")
    if not rows:
        return
    print("| building | R | hypotheses | map features | success | final error [m] | localized at | correct share after first fix |")
    print("|---|---|---|---|---|---|---|---|")
    for r in sorted(rows, key=lambda r: (r["building"], r["submaps"], r.get("hypotheses", ""))):
        print(f"| {r['building']} | {r['submaps']} | {r.get('hypotheses')} | {r['map_features']} | {fmt(r['success'])} | "
              f"{fmt(r['final_error_m'])} | {fmt(r['localized_at'])} | {fmt(r['correct_fraction_after'], 2)} |")
    print()


def flag_line(rs):
    """The confident flag over the successful runs: median share flagged after localizing, runs flagged on at
    least half, median lag localized -> first flagged (never-flagged runs count as endless), median toggles."""
    succ = [r for r in rs if r["success"]]
    share = [r["confident_share_after"] for r in succ if r.get("confident_share_after") is not None]
    lags = [r["first_confident_at"] - r["localized_at"] if r.get("first_confident_at") is not None else float("inf")
            for r in succ if r.get("localized_at") is not None and "first_confident_at" in r]
    changes = [r["flag_changes"] for r in succ if r.get("flag_changes") is not None]
    heading = sum(r.get("confident_wrong_heading", 0) for r in rs)
    conf, wrong, _ = wrong_total(rs)
    return (f"{fmt(statistics.median(share) if share else None, 2)} | "
            f"{sum(v >= 0.5 for v in share)}/{len(share)} | "
            f"{fmt(statistics.median(lags) if lags else None, 1)} | {sum(l == float('inf') for l in lags)} | "
            f"{fmt(statistics.median(changes) if changes else None, 1)} | "
            + (f"{wrong} ({heading} in heading) of {conf} = {100.0 * wrong / conf:.3f}%" if conf else
               f"{wrong} ({heading} in heading) at truth scans"))


FLAG_HEADER = ("median confident share after | runs flagged ≥ half | median lag to flag [scans] | never flagged | "
               "median flag changes | confident but wrong of judged confident scans")
TUNED = {"fr079", "intel"}


def starts_table(rows, title):
    print(f"| {title} | starts succeeding | median localized at | median error after [m] | "
          f"confident judged / wrong (at truth scans) | "
          f"{FLAG_HEADER} |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for b, rs in sorted(by(rows, lambda r: r["building"]).items()):
        seen = "" if b in TUNED else " (unseen)"
        print(f"| {b}{seen} | {summary_line(rs)} | {flag_line(rs)} |")
    unseen = [r for r in rows if r["building"] not in TUNED]
    if unseen:
        print(f"| unseen buildings | {summary_line(unseen)} | {flag_line(unseen)} |")
    print(f"| all | {summary_line(rows)} | {flag_line(rows)} |\n")


def starts():
    rows = load("starts")
    if rows:
        starts_table(rows, "building (R = 15)")


def ingest():
    rows = load("ingest")
    if not rows:
        return
    print("| R | map features (whole map) | how the map is fed | mapper scans fed | mapper scans per CPU second (runs) | median | localizer ms per scan (p99) |")
    print("|---|---|---|---|---|---|---|")
    mode = lambda r: ("beside the localizer, mapper threads" if r["threads"] else "beside the localizer, one thread") \
        if r["live"] else "alone, before the localizer"
    for (submaps, m), rs in sorted(by(rows, lambda r: (r["submaps"], mode(r))).items()):
        rates = [r["map_scans_per_s"] for r in rs]
        features = max(r["map_features"] for r in rs) if not rs[0]["live"] else "—"
        print(f"| {submaps} | {features} | {m} | {rs[0]['mapper_scans']} | {', '.join(f'{v:,.0f}' for v in rates)} | "
              f"{statistics.median(rates):,.0f} | {statistics.median(r['ms_per_scan'] for r in rs):.2f} "
              f"({statistics.median(r['ms_per_scan_p99'] for r in rs):.2f}) |")


# The last commit whose results/*.jsonl judged only the scans with ground truth.
TRUTH_ONLY_COMMIT = "fda3ba5"


def judged_vs_truth():
    """The grid and the starts judged at the truth scans only (TRUTH_ONLY_COMMIT's lines, the same estimates)
    beside the same runs judged on every scan (results/*.jsonl now)."""
    import subprocess
    for part in ("grid", "starts"):
        old = [json.loads(l) for l in subprocess.run(["git", "show", f"{TRUTH_ONLY_COMMIT}:results/{part}.jsonl"],
                                                      capture_output=True, text=True, check=True, cwd=REPO).stdout.splitlines()
               if l.strip() and "failed" not in l]
        new = load(part)
        if not new:
            continue
        print(f"| {part}: building | judged at | succeed | median share flagged after | runs flagged on ≥ half | "
              "median lag [scans] | confident but wrong of judged confident scans |")
        print("|---|---|---|---|---|---|---|")

        def line(rs, dense):
            succ = [r for r in rs if r["success"]]
            share = [r["confident_share_after"] for r in succ if r.get("confident_share_after") is not None]
            lags = [r["first_confident_at"] - r["localized_at"] if r.get("first_confident_at") is not None
                    else float("inf") for r in succ if r.get("localized_at") is not None]
            conf = sum(r["confident_judged"] if dense else r["confident_scans"] for r in rs)
            wrong = sum(r["confident_wrong"] for r in rs)
            return (f"{len(succ)}/{len(rs)} | {fmt(statistics.median(share) if share else None, 2)} | "
                    f"{sum(v >= 0.5 for v in share)}/{len(share)} | {fmt(statistics.median(lags) if lags else None, 1)} | "
                    f"{wrong} of {conf} ({100.0 * wrong / conf if conf else 0:.3f}%)")
        for b in sorted({r["building"] for r in new}) + ["all"]:
            o = old if b == "all" else [r for r in old if r["building"] == b]
            n = new if b == "all" else [r for r in new if r["building"] == b]
            print(f"| {b} | truth scans ({TRUTH_ONLY_COMMIT}) | {line(o, False)} |")
            print(f"| {b} | every scan | {line(n, True)} |")
        print()


FLAG_BEFORE_COMMIT = "aefa4ee"  # the last commit with the rule-stack flag (issue 66's deliverables 2-4 came after)


def flag_before_after():
    """The flag before its rework (FLAG_BEFORE_COMMIT's lines, the same estimates) beside now, judged on every
    scan: the 16 default scenarios, the 100 starts, our held-out windows and the live grid."""
    import subprocess
    print(f"| part: building | flag | succeed | {FLAG_HEADER} |")
    print("|---|---|---|---|---|---|---|---|---|")
    for part in ("grid", "starts", "heldout", "live"):
        old = [json.loads(l) for l in subprocess.run(["git", "show", f"{FLAG_BEFORE_COMMIT}:results/{part}.jsonl"],
                                                      capture_output=True, text=True, check=True, cwd=REPO).stdout.splitlines()
               if l.strip() and "failed" not in l]
        new = load(part)
        for b in sorted({r["building"] for r in new}) + ["all"]:
            for label, rows in ((f"before ({FLAG_BEFORE_COMMIT})", old), ("now", new)):
                rs = rows if b == "all" else [r for r in rows if r["building"] == b]
                if rs:
                    name = f"**{part}: all**" if b == "all" else f"{part}: {b}"
                    print(f"| {name} | {label} | {sum(r['success'] for r in rs)}/{len(rs)} | {flag_line(rs)} |")
    print()


def heldout():
    rows = load("heldout")
    if rows:
        starts_table(rows, "held-out window (R = 15, seed 3)")


def starts_seeded():
    rows = load("starts_seeded")
    for seed, rs in sorted(by(rows, lambda r: r.get("seed")).items(), key=str):
        starts_table(rs, f"building (R = 15, seed {seed})")


if __name__ == "__main__":
    parts = sys.argv[1:] or ["grid", "orders", "ablation", "starts"]
    for p in parts:
        globals()[p]()
