#!/usr/bin/env python3
"""The fleet on loopback (docs/fleet.md): starts its own redis-server(s) on free
loopback ports and stops them, and runs mapper and localizer processes of
$LSHLOC (default build/bin/lshloc) against them:

  functional  4 mappers publish fr079's default scenario (R = 15) at once, then
              2 localizers (eval --map-redis) localize its target
  ingest      scans/s of those 4 mappers into one Redis, publishing together
  kill mapper a mapper killed -9 mid-stream: the follower's map holds every
              acknowledged update (what the streams hold), nothing more
  restart     Redis (AOF, appendfsync everysec) restarted while a mapper
              publishes and a follower follows: no update lost, none twice
  localizer   a localizer killed -9, restarted from a snapshot, reaches the
              map of one that read everything
  catch-up    a late localizer on a 1e6-feature map: from a snapshot and from
              the stream alone
  cluster     a 3-master Redis Cluster (scripts/redis_cluster.sh): the 4 mappers
              publish there, and a localizer's per-scan trace equals the
              single-Redis one byte for byte
  throughput  ingest with 1 and 4 mappers (fr079 R = 15) and with 16
              (simulated buildings, the catch-up case's first half)

Prints progress on stderr and one JSON line last on stdout; exits 0 only when
every case passed. Needs the shared logs (../shared/data or $LSHLOC_DATA).
Usage: LSHLOC=build/bin/lshloc scripts/fleet_test.sh [--cases functional,cluster] [--smoke]"""
import argparse
import filecmp
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LSHLOC = os.path.abspath(os.environ.get("LSHLOC", os.path.join(ROOT, "build/bin/lshloc")))


def log(msg):
    print(f"fleet_test: {msg}", file=sys.stderr, flush=True)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Redis:
    """A redis-server of this script's own, on loopback, with an AOF."""

    def __init__(self, work, name):
        self.dir = os.path.join(work, name)
        os.makedirs(self.dir, exist_ok=True)
        self.port = free_port()
        self.proc = None
        self.start()

    def start(self):
        self.proc = subprocess.Popen(
            ["redis-server", "--port", str(self.port), "--bind", "127.0.0.1", "--save", "", "--appendonly", "yes",
             "--appendfsync", "everysec", "--dir", self.dir, "--logfile", "redis.log"])
        for _ in range(100):
            if self.cli("PING").strip() == "PONG":
                return
            time.sleep(0.05)
        raise RuntimeError(f"redis-server on port {self.port} did not start")

    def stop(self, sig=signal.SIGTERM):
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(sig)
            self.proc.wait(timeout=30)
        self.proc = None

    def cli(self, *args):
        r = subprocess.run(["redis-cli", "-p", str(self.port), *args], capture_output=True, text=True)
        return r.stdout

    @property
    def url(self):
        return f"redis://127.0.0.1:{self.port}"

    def stream_lengths(self, prefix):
        keys = [k for k in self.cli("--scan", "--pattern", f"{prefix}:{{*}}:log").split() if k]
        return sum(int(self.cli("XLEN", k).strip() or 0) for k in keys)


def run(args, **kw):
    return subprocess.run([LSHLOC, *args], capture_output=True, text=True, **kw)


def last_json(text):
    lines = [l for l in text.splitlines() if l.strip().startswith("{")]
    return json.loads(lines[-1]) if lines else None


def publish_scenario(url, prefix, mappers, submaps):
    """`mappers` processes publish fr079's default scenario (R = `submaps`) at
    once, each its part; returns (scans, seconds from the first start to the
    last finish) or None."""
    procs = [subprocess.Popen([LSHLOC, "mapper-scenario", "--redis", url, "--prefix", prefix, "--building", "fr079",
                               "--submaps", str(submaps), "--part", f"{k}/{mappers}", "--together", str(mappers)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for k in range(mappers)]
    done = [p.communicate() for p in procs]
    outs = [last_json(o) for o, _ in done]
    if any(o is None for o in outs) or any(p.returncode for p in procs):
        log("a mapper failed: " + " | ".join(e for _, e in done))
        return None
    return sum(o["scans"] for o in outs), max(o["finished_at"] for o in outs) - min(o["started_at"] for o in outs)


def localize_scenario(url, prefix, submaps, trace=None):
    args = ["eval", "--building", "fr079", "--submaps", str(submaps), "--map-redis", url, "--map-prefix", prefix,
            "--json"]
    return subprocess.Popen([LSHLOC, *args, *(["--trace", trace] if trace else [])], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def functional_and_ingest(redis, work, result, submaps):
    log(f"ingest: 1 mapper publishes fr079 R={submaps} alone")
    one = publish_scenario(redis.url, "one", 1, submaps)
    if one:
        result["ingest_scans_per_s_1_mapper"] = round(one[0] / one[1]) if one[1] > 0 else 0
        log(f"ingest: {one[0]} scans in {one[1]:.2f} s = {result['ingest_scans_per_s_1_mapper']} scans/s")
    log(f"functional: 4 mappers publish fr079 R={submaps} at once, then 2 localizers")
    four = publish_scenario(redis.url, "fn", 4, submaps)
    if four is None:
        return False
    scans, window = four
    result["ingest_scans_per_s_4_mappers"] = round(scans / window) if window > 0 else 0
    result["ingest_scans"] = scans
    log(f"ingest: {scans} scans in {window:.2f} s = {result['ingest_scans_per_s_4_mappers']} scans/s")
    locs = [localize_scenario(redis.url, "fn", submaps, os.path.join(work, "single.trace.csv") if k == 0 else None)
            for k in range(2)]
    answers = [last_json(p.communicate()[0]) for p in locs]
    result["localizers"] = len(locs)
    result["localizers_correct"] = sum(1 for a in answers if a and a.get("success"))
    result["localizer_final_error_m"] = [a.get("final_error_m") if a else None for a in answers]
    log(f"localizers correct: {result['localizers_correct']}/2, final errors {result['localizer_final_error_m']}")
    return result["localizers_correct"] == 2


def cluster(work, result, submaps):
    log(f"cluster: a 3-master Redis Cluster (scripts/redis_cluster.sh); 4 mappers publish fr079 R={submaps}, "
        "a localizer")
    script, where = os.path.join(ROOT, "scripts", "redis_cluster.sh"), os.path.join(work, "cluster")
    started = subprocess.run([script, "start", where], capture_output=True, text=True)
    if started.returncode:
        log("cluster: did not start: " + started.stderr)
        return False
    try:
        url = started.stdout.split()[-1]
        four = publish_scenario(url, "fn", 4, submaps)
        if four is None:
            return False
        result["ingest_scans_per_s_4_mappers_cluster"] = round(four[0] / four[1]) if four[1] > 0 else 0
        trace = os.path.join(work, "cluster.trace.csv")
        answer = last_json(localize_scenario(url, "fn", submaps, trace).communicate()[0])
        single = os.path.join(work, "single.trace.csv")
        same = answer is not None and os.path.exists(single) and filecmp.cmp(single, trace, shallow=False)
        result["cluster_final_error_m"] = answer.get("final_error_m") if answer else None
        log(f"cluster: ingest {result['ingest_scans_per_s_4_mappers_cluster']} scans/s; the localizer's per-scan "
            f"trace is {'byte-identical to' if same else 'NOT the same as'} the single Redis run's "
            f"(final error {result['cluster_final_error_m']} m)")
        return same
    finally:
        subprocess.run([script, "stop", where])


def kill_mapper(redis, result):
    log("kill mapper: a mapper killed -9 while it publishes; a follower follows")
    mapper = subprocess.Popen([LSHLOC, "mapper-scenario", "--redis", redis.url, "--prefix", "km", "--building", "fr101",
                               "--submaps", "4", "--rate", "2000"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    for _ in range(600):  # until the mapper publishes
        if redis.stream_lengths("km") > 0:
            break
        time.sleep(0.1)
    follower = subprocess.Popen([LSHLOC, "map", "from-redis", redis.url, "--prefix", "km", "--out",
                                 os.path.join(redis.dir, "km.map"), "--follow", "3"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.0)
    mapper.send_signal(signal.SIGKILL)
    mapper.wait()
    acknowledged = redis.stream_lengths("km")
    stdout, stderr = follower.communicate()
    out = last_json(stdout)
    if out is None:
        log("the follower failed: " + stderr)
        return None
    lost = acknowledged - out["scans"]
    result["kill_mapper_acknowledged"] = acknowledged
    log(f"kill mapper: {acknowledged} acknowledged updates, the follower's map holds {out['scans']}")
    return lost, out["duplicates"]


def restart_redis(redis, result):
    log("restart: Redis restarted (AOF) while a mapper publishes and a follower follows")
    follower_out = os.path.join(redis.dir, "rr.map")
    mapper = subprocess.Popen([LSHLOC, "mapper-scenario", "--redis", redis.url, "--prefix", "rr", "--building", "fr101",
                               "--submaps", "4", "--rate", "1500"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
    for _ in range(600):
        if redis.stream_lengths("rr") > 0:
            break
        time.sleep(0.1)
    follower = subprocess.Popen([LSHLOC, "map", "from-redis", redis.url, "--prefix", "rr", "--out", follower_out,
                                 "--follow", "4"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.0)
    redis.stop()
    time.sleep(0.5)
    redis.start()
    mstdout, mstderr = mapper.communicate()
    fstdout, fstderr = follower.communicate()
    mout, out = last_json(mstdout), last_json(fstdout)
    if mout is None or out is None:
        log("restart: a process failed: " + mstderr + fstderr)
        return None
    acknowledged = redis.stream_lengths("rr")
    result["restart_reconnects"] = {"mapper": mout.get("reconnects"), "follower": out.get("reconnects")}
    log(f"restart: stream holds {acknowledged}, mapper published {mout['scans']}, the follower's map "
        f"{out['scans']} ({out['duplicates']} duplicates skipped, {out['reconnects']} reconnects)")
    duplicates_in_stream = acknowledged - mout["scans"]
    return acknowledged - out["scans"], max(0, duplicates_in_stream), out["scans"] - mout["scans"]


def restart_localizer(redis, work, result):
    log("localizer: a localizer killed -9, restarted from a snapshot")
    sim = os.path.join(work, "sim")
    run(["simulate", "--out", sim, "--buildings", "2", "--seed", "4", "--scans", "800"], check=True)
    logs = [os.path.join(sim, f"sim-4-00{k}", f"sim-4-00{k}-corrected.log.gz") for k in range(2)]
    target = os.path.join(sim, "sim-4-001", "sim-4-001.log.gz")
    run(["mapper", "--redis", redis.url + "?prefix=kl", logs[0]], check=True)
    mapper = subprocess.Popen([LSHLOC, "mapper", "--redis", redis.url + "?prefix=kl", "--rate", "400", logs[1]],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    time.sleep(0.3)
    loc = subprocess.Popen([LSHLOC, "localize", "--map", redis.url + "?prefix=kl", "--target", target,
                            "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    time.sleep(0.5)
    loc.send_signal(signal.SIGKILL)
    loc.wait()
    snap = os.path.join(work, "kl.map")
    run(["map", "from-redis", redis.url, "--prefix", "kl", "--out", snap], check=True)
    mapper.wait()
    again = run(["localize", "--map", redis.url + "?prefix=kl&snapshot=" + snap, "--target", target,
                 "--start", "400", "--length", "100", "--json"])
    full = run(["map", "from-redis", redis.url, "--prefix", "kl", "--out", os.path.join(work, "kl-full.map")])
    a, f = last_json(again.stdout), last_json(full.stdout)
    if a is None or f is None:
        log("localizer: " + again.stderr + full.stderr)
        return False
    log(f"localizer: restarted from the snapshot it holds {a['map_log']['map_scans']} scans "
        f"({a['map_log']['history_updates']} read after the snapshot); the whole log gives {f['scans']}")
    return a["map_log"]["map_scans"] == f["scans"] and a["map_features"] == f["features"]


def catch_up(redis, work, result):
    log("catch-up: a late localizer on a 1e6-feature map")
    sim = os.path.join(work, "big")
    run(["simulate", "--out", sim, "--buildings", "32", "--seed", "9", "--scans", "3300"], check=True)
    logs = sorted(os.path.join(sim, d, f"{d}-corrected.log.gz") for d in os.listdir(sim)
                  if os.path.isdir(os.path.join(sim, d)))
    # The first 16 publish at once: the ingest figure with 16 mappers.
    procs = [subprocess.Popen([LSHLOC, "mapper", "--redis", redis.url + "?prefix=big", "--together", "16", l],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True) for l in logs[:16]]
    outs = [last_json(p.communicate()[0]) for p in procs]
    if all(outs):
        scans = sum(o["scans"] for o in outs)
        window = max(o["finished_at"] for o in outs) - min(o["started_at"] for o in outs)
        result["ingest_scans_per_s_16_mappers"] = round(scans / window) if window > 0 else 0
        log(f"ingest: 16 mappers (simulated buildings) {scans} scans in {window:.2f} s = "
            f"{result['ingest_scans_per_s_16_mappers']} scans/s")
    procs = [subprocess.Popen([LSHLOC, "mapper", "--redis", redis.url + "?prefix=big", l],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for l in logs[16:]]
    for p in procs:
        p.wait()
    snap = os.path.join(work, "big.map")
    made = last_json(run(["map", "from-redis", redis.url, "--prefix", "big", "--out", snap]).stdout)
    target = logs[0].replace("-corrected", "")
    args = ["--target", target, "--length", "3", "--json"]
    from_snap = last_json(run(["localize", "--map", redis.url + "?prefix=big&snapshot=" + snap] + args).stdout)
    from_stream = last_json(run(["localize", "--map", redis.url + "?prefix=big"] + args).stdout)
    result["catch_up_map_features"] = made["features"] if made else None
    result["catch_up_s_1e6_snapshot"] = round(from_snap["map_log"]["catch_up_s"], 3) if from_snap else None
    result["catch_up_s_1e6_stream"] = round(from_stream["map_log"]["catch_up_s"], 3) if from_stream else None
    log(f"catch-up: {result['catch_up_map_features']} features: {result['catch_up_s_1e6_snapshot']} s from a "
        f"snapshot, {result['catch_up_s_1e6_stream']} s from the stream alone")
    return made is not None and made["features"] >= 1e6 and from_snap is not None


CASES = ["functional", "faults", "localizer", "catch_up", "cluster"]


def main():
    ap = argparse.ArgumentParser(description="The fleet on loopback: see the module's docstring.")
    ap.add_argument("--cases", default=",".join(CASES),
                    help="comma-separated, of " + ", ".join(CASES) + " (cluster compares with functional's run, "
                         "so it brings functional along); default all")
    ap.add_argument("--smoke", action="store_true",
                    help="the test suite's run: fr079 at R = 4 instead of 15, and no ingest floor (speed is "
                         "measured by the full run and the benchmarks, not asserted in tests)")
    a = ap.parse_args()
    submaps = 4 if a.smoke else 15  # R of the fr079 scenario the mappers publish
    cases = set(a.cases.split(","))
    if not cases <= set(CASES):
        ap.error(f"--cases: expected some of {', '.join(CASES)}, got {a.cases}")
    if "cluster" in cases:
        cases.add("functional")
    if not shutil.which("redis-server"):
        print("fleet_test: redis-server not found (scripts/setup.sh installs it)", file=sys.stderr)
        return 2
    work = tempfile.mkdtemp(prefix="lshloc-fleet-")
    # Every mapper and localizer process loads the same scenario: SLAM poses
    # the buildings without a corrected log once, not once per process.
    os.environ.setdefault("LSHLOC_SLAM_CACHE", os.path.join(work, "slam-cache"))
    redis = Redis(work, "redis")
    result = {"localizers": 0, "localizers_correct": 0, "lost_updates": None, "duplicate_updates": None,
              "restarted_localizer_same_map": False, "cluster_same_estimates": False,
              "ingest_scans_per_s_4_mappers": 0, "catch_up_s_1e6_snapshot": None}
    ok = {}
    try:
        if "functional" in cases:
            ok["functional"] = functional_and_ingest(redis, work, result, submaps)
            if not a.smoke:
                ok["ingest"] = result["ingest_scans_per_s_4_mappers"] >= 5000
        if "faults" in cases:
            km = kill_mapper(redis, result)
            rr = restart_redis(redis, result)
            if km and rr:
                result["lost_updates"] = max(0, km[0]) + max(0, rr[0])
                result["duplicate_updates"] = rr[1]
            ok["faults"] = result["lost_updates"] == 0 and result["duplicate_updates"] == 0
        if "localizer" in cases:
            result["restarted_localizer_same_map"] = restart_localizer(redis, work, result)
            ok["localizer"] = result["restarted_localizer_same_map"]
        if "catch_up" in cases:
            ok["catch_up"] = catch_up(redis, work, result) and result["catch_up_s_1e6_snapshot"] <= 10
        if "cluster" in cases:
            ok["cluster"] = result["cluster_same_estimates"] = cluster(work, result, submaps)
    finally:
        redis.stop()
        shutil.rmtree(work, ignore_errors=True)
    result["cases"] = ok
    print(json.dumps(result), flush=True)
    return 0 if all(ok.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
