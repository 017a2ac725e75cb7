#!/usr/bin/env bash
# A robot in the unmapped part of its own building: each building with a raw
# log, a corrected log and ground truth is mapped from one half of its
# corrected log (the first half, then the last), and raw windows whose true
# poses all stay >= 4 m from every mapped pose are localized in that map.
# Where the robot is, the map holds nothing; the walls it sees may still be in
# the map, seen from afar, so a confident estimate is judged against the truth
# (`lshloc judge`, every scan: docs/design.md section 6), not counted wrong
# outright. Writes OUT/BUILDING-HALF-START.{tum,tum.csv,json,judged.json} and
# prints one line per window with a wrong confident scan, then a summary line.
#
#   scripts/eval/unmapped_part.sh OUT [--config FILE] [--windows N] [--length L] [--clearance M]
#   (LSHLOC, LSHLOC_DATA as elsewhere; JOBS parallel runs, default 2)
set -euo pipefail
out=${1:?usage: scripts/eval/unmapped_part.sh OUT [--config FILE] [--windows N] [--length L] [--clearance M]}
shift
config="" windows=2 length=300 clearance=4
while [ $# -gt 0 ]; do
  case $1 in
    --config) config=${2:?--config needs a FILE}; shift 2 ;;
    --windows) windows=${2:?--windows needs N}; shift 2 ;;
    --length) length=${2:?--length needs L}; shift 2 ;;
    --clearance) clearance=${2:?--clearance needs M}; shift 2 ;;
    *) echo "unmapped_part: unknown option $1" >&2; exit 2 ;;
  esac
done
[[ $windows =~ ^[1-9][0-9]*$ && $length =~ ^[1-9][0-9]*$ && $clearance =~ ^[0-9]+([.][0-9]+)?$ ]] ||
  { echo "unmapped_part: --windows and --length take positive integers, --clearance metres" >&2; exit 2; }
here=$(cd "$(dirname "$0")/../.." && pwd)
lshloc=${LSHLOC:-$here/build/bin/lshloc}
data=${LSHLOC_DATA:-$here/../shared/data}
[ -d "$data" ] || { echo "unmapped_part: no data directory $data" >&2; exit 1; }
[ -z "$config" ] || [ -f "$config" ] || { echo "unmapped_part: no config file $config" >&2; exit 1; }
mkdir -p "$out/maps"
# The halves' logs and the windows: OUT/jobs.txt lines "BUILDING-HALF RAW POSES START".
LSHLOC_DATA="$data" "$lshloc" info --buildings >"$out/buildings.jsonl"
python3 - "$out" "$windows" "$length" "$clearance" <<'PY'
import bisect, gzip, json, math, os, sys
out, windows, length, clearance = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
def scan_stamps(path):  # FLASER n r_1..r_n x y theta odom_x odom_y odom_theta ipc_timestamp ...
    return [float(p[2 + int(p[1]) + 6]) for p in (l.split() for l in gzip.open(path, "rt")) if p and p[0] == "FLASER"]
jobs = []
for b in map(json.loads, open(os.path.join(out, "buildings.jsonl"))):
    if not (b["raw_log"] and b["corrected_log"] and b["poses"]):
        continue
    lines = gzip.open(b["corrected_log"], "rt").read().splitlines()
    scans = [i for i, l in enumerate(lines) if l.startswith("FLASER")]
    truth = sorted(tuple(map(float, l.split()[:4])) for l in open(b["poses"]) if l.strip() and not l.startswith("#"))
    stamps = scan_stamps(b["raw_log"])
    cut = scans[len(scans) // 2]
    keep = [l for l in lines if l.startswith("PARAM")]  # the mount and other settings, whichever half
    for half, part in (("first", lines[:cut]), ("last", lines[cut:])):
        name = f"{b['building']}-{half}"
        path = os.path.join(out, "maps", name + ".log.gz")
        if not os.path.exists(path):
            with gzip.open(path, "wt") as f:
                f.write("\n".join(keep + [l for l in part if not l.startswith("PARAM")]) + "\n")
        mapped = [(float(p[2 + int(p[1])]), float(p[3 + int(p[1])])) for p in (l.split() for l in part)
                  if p and p[0] == "FLASER"]
        cell = {}  # mapped poses by 4 m cell: a window's truth is checked against the nine around it
        for x, y in mapped:
            cell.setdefault((math.floor(x / clearance), math.floor(y / clearance)), []).append((x, y))
        def clear(x, y):
            cx, cy = math.floor(x / clearance), math.floor(y / clearance)
            return all(math.hypot(x - px, y - py) >= clearance for dx in (-1, 0, 1) for dy in (-1, 0, 1)
                       for px, py in cell.get((cx + dx, cy + dy), []))
        ts = [t[0] for t in truth]
        chosen = []
        for s in range(0, len(stamps) - length, 50):
            lo, hi = bisect.bisect_left(ts, stamps[s]), bisect.bisect_right(ts, stamps[s + length - 1])
            if hi - lo >= 5 and all(clear(t[1], t[2]) for t in truth[lo:hi]):
                if not chosen or s - chosen[-1] >= 2 * length:
                    chosen.append(s)
            if len(chosen) == windows:
                break
        jobs += [f"{name} {b['raw_log']} {b['poses']} {s}" for s in chosen]
open(os.path.join(out, "jobs.txt"), "w").write("".join(j + "\n" for j in jobs))
PY
for log in "$out"/maps/*.log.gz; do
  m=${log%.log.gz}.map
  [ -s "$m" ] || "$lshloc" map build --out "$m" "$log" >/dev/null 2>&1 || { echo "unmapped_part: map build $log failed" >&2; exit 1; }
done
export lshloc out config length
xargs -P "${JOBS:-2}" -L 1 bash -c '
  stem=$out/$0-$3 map=$out/maps/$0.map
  [ -s "$stem.json" ] || "$lshloc" localize --map "$map" --target "$1" --start "$3" --length "$length" --out "$stem.tum" \
    --json ${config:+--config "$config"} >"$stem.json" 2>/dev/null || [ -s "$stem.json" ] ||
    { echo "unmapped_part: $0 at $3 failed" >&2; rm -f "$stem.json"; exit 0; }
  submap=$("$lshloc" map info "$map" --json | python3 -c "import json, sys; print(json.load(sys.stdin)[\"meta\"][\"submaps\"][0][\"submap\"])")
  "$lshloc" judge "$stem.tum.csv" --log "$1" --truth "$2" --submap "$submap" --json >"$stem.judged.json" ||
    { echo "unmapped_part: judging $0 at $3 failed" >&2; rm -f "$stem.judged.json"; }
' <"$out/jobs.txt"
python3 - "$out" <<'PY'
import json, os, sys
out = sys.argv[1]
s = dict(windows=0, failed=0, flagged_windows=0, wrong_windows=0, scans=0, judged=0, confident=0, wrong=0,
         longest_wrong_run=0)
for line in open(os.path.join(out, "jobs.txt")):
    name, _, _, start = line.split()
    s["windows"] += 1
    path = os.path.join(out, f"{name}-{start}.judged.json")
    if not os.path.exists(path):
        s["failed"] += 1
        continue
    j = json.load(open(path))
    s["scans"] += j["scans"]; s["judged"] += j["judged_scans"]; s["confident"] += j["confident_scans"]
    s["wrong"] += j["confident_wrong"]; s["flagged_windows"] += j["confident_scans"] > 0
    s["longest_wrong_run"] = max(s["longest_wrong_run"], j["longest_confident_wrong_run"])
    if j["confident_wrong"]:
        s["wrong_windows"] += 1
        print(f"wrong: {name} at {start}: {j['confident_wrong']} of {j['confident_scans']} confident scans, "
              f"first at {j['confident_wrong_scans'][0]}")
print(json.dumps(s))
PY
