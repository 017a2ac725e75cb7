#!/usr/bin/env python3
"""A fleet's localizer against the batch run, on the 16 default scenarios (4
buildings x R in 1 4 9 15; docs/fleet.md "Same answers as from files").

For each scenario, 4 mapper processes (`lshloc mapper-scenario --building B --submaps R
--part k/4 --together 4`) publish its submaps into a Redis of this script's own
(loopback, a free port), a localizer runs `eval --map-redis ... --trace`, and
the batch run `eval ... --trace` builds the same map from the logs. The two
per-scan traces (estimate, truth, error, scores; no timings) are compared byte
for byte. One JSON line per scenario goes to results/fleet_vs_batch.jsonl,
and a summary line to stdout; exits 0 only when every trace is the same.
Usage: LSHLOC=build/bin/lshloc scripts/eval/fleet_vs_batch.py [--buildings fr079,...] [--submaps 1,4,9,15]"""
import argparse
import filecmp
import json
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # fleet_test.py
from fleet_test import LSHLOC, ROOT, Redis, last_json, log  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--buildings", default="fr079,fr101,intel,aces")
    ap.add_argument("--submaps", default="1,4,9,15")
    ap.add_argument("--mappers", type=int, default=4)
    ap.add_argument("--out", default=os.path.join(ROOT, "results", "fleet_vs_batch.jsonl"))
    a = ap.parse_args()
    if not shutil.which("redis-server"):
        print("fleet_vs_batch: redis-server not found (scripts/setup.sh installs it)", file=sys.stderr)
        return 2
    work = tempfile.mkdtemp(prefix="lshloc-fleet-batch-")
    redis = Redis(work, "redis")
    rows = []
    try:
        for b in a.buildings.split(","):
            for r in a.submaps.split(","):
                prefix = f"{b}-{r}"
                mappers = [subprocess.Popen([LSHLOC, "mapper-scenario", "--redis", redis.url, "--prefix", prefix,
                                             "--building", b, "--submaps", r, "--part", f"{k}/{a.mappers}",
                                             "--together", str(a.mappers)], stdout=subprocess.PIPE,
                                            stderr=subprocess.PIPE, text=True) for k in range(a.mappers)]
                outs = [m.communicate() for m in mappers]
                if any(m.returncode for m in mappers):
                    raise RuntimeError(f"{prefix}: a mapper failed: " + " | ".join(e for _, e in outs))
                scenario = ["eval", "--building", b, "--submaps", r, "--json"]
                fleet_trace, batch_trace = (os.path.join(work, f"{prefix}.{k}.csv") for k in ("fleet", "batch"))
                fleet = subprocess.run([LSHLOC, *scenario, "--map-redis", redis.url, "--map-prefix", prefix,
                                        "--trace", fleet_trace], capture_output=True, text=True)
                batch = subprocess.run([LSHLOC, *scenario, "--trace", batch_trace], capture_output=True, text=True)
                f, bt = last_json(fleet.stdout), last_json(batch.stdout)
                same = f is not None and bt is not None and filecmp.cmp(fleet_trace, batch_trace, shallow=False)
                row = {"building": b, "submaps": int(r), "mappers": a.mappers,
                       "published_scans": sum(last_json(o)["scans"] for o, _ in outs),
                       "fleet_success": f.get("success") if f else None,
                       "batch_success": bt.get("success") if bt else None,
                       "fleet_final_error_m": f.get("final_error_m") if f else None,
                       "batch_final_error_m": bt.get("final_error_m") if bt else None,
                       "trace_rows": sum(1 for _ in open(batch_trace)) - 1 if bt else None,
                       "same_trace": same}
                rows.append(row)
                log(f"{prefix}: {'same trace' if same else 'TRACES DIFFER'}; success fleet "
                    f"{row['fleet_success']} / batch {row['batch_success']}")
    finally:
        redis.stop()
        shutil.rmtree(work, ignore_errors=True)
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as out:
        for row in rows:
            out.write(json.dumps(row) + "\n")
    same = sum(1 for r in rows if r["same_trace"])
    print(json.dumps({"scenarios": len(rows), "same_trace": same,
                      "fleet_successes": sum(1 for r in rows if r["fleet_success"]),
                      "batch_successes": sum(1 for r in rows if r["batch_success"])}))
    return 0 if same == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
