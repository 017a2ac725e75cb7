#!/usr/bin/env bash
# Map store speed and size (BENCHMARKS.md, "Map store"): for the 15-building
# real map (eval fr079 R = 15) and synthetic maps of R = 40 and 100 submaps
# (eval adds synthetic buildings beyond the 15 real ones):
#   - the whole-process CPU of a 5-scan eval that builds the map from its
#     logs (and saves it), against one that loads the saved map;
#   - save and load times (load: `map info --json`, timed inside), file bytes
#     per feature;
# the append throughput of `map append` at several fsync batch sizes; and
# `lshloc localize` of 100 fr079 scans in the 15 buildings' logs against the
# same map built once and saved (whole-process CPU, trajectories compared).
# Writes results/map_store.jsonl (one line per measurement) and prints a table.
# Environment: LSHLOC (binary), LSHLOC_DATA, SUBMAPS ("15 40 100"), OUT (results/map_store.jsonl).
set -euo pipefail
cd "$(dirname "$0")/../.."
LSHLOC=${LSHLOC:-build/bin/lshloc}
export LSHLOC_DATA=${LSHLOC_DATA:-../shared/data}
SUBMAPS=${SUBMAPS:-"15 40 100"}
OUT=${OUT:-results/map_store.jsonl}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$(dirname "$OUT")"
: >"$OUT"

cpu_of() { awk '{print $2 + $3}' "$1"; }  # /usr/bin/time -f '%e %U %S': user + system

for r in $SUBMAPS; do
  echo "R = $r: building the map from its logs, saving it ..." >&2
  /usr/bin/time -f '%e %U %S' -o "$work/t_build" "$LSHLOC" eval --building fr079 --submaps "$r" --length 5 \
    --save-map "$work/r$r.map" --json >"$work/build.json" 2>"$work/build.err"
  /usr/bin/time -f '%e %U %S' -o "$work/t_load" "$LSHLOC" eval --building fr079 --submaps "$r" --length 5 \
    --load-map "$work/r$r.map" --json >"$work/load.json" 2>"$work/load.err"
  best_load=""
  for _ in 1 2 3; do  # the machine is noisy: the best of three loads
    "$LSHLOC" map info "$work/r$r.map" --json >"$work/info.json"
    l=$(python3 -c "import json; print(json.load(open('$work/info.json'))['load_cpu_s'])")
    if [ -z "$best_load" ] || python3 -c "import sys; sys.exit(not $l < $best_load)"; then best_load=$l; cp "$work/info.json" "$work/best.json"; fi
  done
  python3 - "$r" "$work/build.json" "$work/load.json" "$work/best.json" "$(cpu_of "$work/t_build")" \
    "$(cpu_of "$work/t_load")" >>"$OUT" <<'EOF'
import json, sys
r, build, load, info = int(sys.argv[1]), *(json.load(open(p)) for p in sys.argv[2:5])
build_cpu, load_cpu = float(sys.argv[5]), float(sys.argv[6])
f = info["features"]
print(json.dumps({
    "kind": "map", "submaps": r, "features": f, "file_bytes": info["bytes"],
    "file_bytes_per_feature": info["bytes"] / f, "memory_bytes_per_feature": info["memory_bytes_per_feature"],
    "sections_bytes_per_feature": {s["name"]: s["bytes"] / f for s in info["sections"]},
    "map_build_s": build["map_build_s"], "save_s": build["map_save_s"],
    "load_s": info["load_s"], "load_cpu_s": info["load_cpu_s"], "load_s_per_1e6_features": info["load_s"] * 1e6 / f,
    "eval5_cpu_building_s": build_cpu, "eval5_cpu_loading_s": load_cpu, "eval5_cpu_ratio": build_cpu / load_cpu,
    "same_final_estimate": build["final_error_m"] == load["final_error_m"],
}))
EOF
done

echo "saved vs built maps: per-scan traces of the default scenarios at R = 15 ..." >&2
for b in ${IDENTITY_BUILDINGS:-fr079 fr101 intel aces}; do
  "$LSHLOC" eval --building "$b" --submaps 15 --save-map "$work/$b.map" --trace "$work/$b-built.csv" --json \
    >"$work/$b-built.json" 2>/dev/null
  "$LSHLOC" eval --building "$b" --submaps 15 --load-map "$work/$b.map" --trace "$work/$b-loaded.csv" --json \
    >"$work/$b-loaded.json" 2>/dev/null
  same=false; cmp -s "$work/$b-built.csv" "$work/$b-loaded.csv" && same=true
  python3 -c "
import json, sys
a, b = json.load(open(sys.argv[2])), json.load(open(sys.argv[3]))
print(json.dumps({'kind': 'identity', 'building': sys.argv[1], 'submaps': 15, 'scans': sum(1 for _ in open(sys.argv[5])) - 1,
                  'trace_identical': sys.argv[4] == 'true', 'success': a['success'], 'final_error_m': a['final_error_m'],
                  'map_build_s': a['map_build_s'], 'map_load_s': b['map_load_s']}))" \
    "$b" "$work/$b-built.json" "$work/$b-loaded.json" "$same" "$work/$b-built.csv" >>"$OUT"
done

echo "append throughput ..." >&2
"$LSHLOC" map build --out "$work/base.map" "$LSHLOC_DATA/intel/intel.gfs.log.gz" >/dev/null 2>&1
for n in 1 16 256; do
  cp "$work/base.map" "$work/a.map"
  "$LSHLOC" map append "$work/a.map" "$LSHLOC_DATA/fr079/fr079-complete.gfs.log.gz" --sync-every "$n" --json |
    python3 -c "import json,sys; j=json.load(sys.stdin); print(json.dumps({'kind': 'append', 'sync_every': j['sync_every'], 'scans': j['appended_scans'], 'seconds': j['seconds'], 'scans_per_s': j['scans_per_s']}))" >>"$OUT"
done

echo "localize: 15 logs against the saved map ..." >&2
D=$LSHLOC_DATA
logs=("$D/intel/intel.gfs.log.gz" "$D/aces/aces-corrected.log.gz" "$D/fr101/fr101.carmen.gfs.log.gz"
      "$D/mit-csail/csail.corrected.log.gz" "$D/fr079/fr079-complete.gfs.log.gz")
for f in "$D"/radish-gfs-corrected/*-corrected.log.gz; do logs+=("$f"); done
logs+=("$D/fr-clinic/fr-clinic.recon-from-bag.log.gz,slam" "$D/mit-killian/mit-killian.recon-from-bag.log.gz,slam")
maps=(); for l in "${logs[@]}"; do maps+=(--map "$l"); done
"$LSHLOC" map build --out "$work/all.map" "${logs[@]}" >/dev/null 2>&1
target=(--target "$D/fr079/fr079.recon-from-bag.log.gz" --start 2000 --length 100)
/usr/bin/time -f '%e %U %S' -o "$work/t_logs" "$LSHLOC" localize "${maps[@]}" "${target[@]}" --out "$work/logs.tum" --json \
  >"$work/logs.json" 2>/dev/null
/usr/bin/time -f '%e %U %S' -o "$work/t_saved" "$LSHLOC" localize --map "$work/all.map" "${target[@]}" \
  --out "$work/saved.tum" --json >"$work/saved.json" 2>/dev/null
same=false; cmp -s "$work/logs.tum" "$work/saved.tum" && cmp -s "$work/logs.tum.csv" "$work/saved.tum.csv" && same=true
python3 -c "
import json, sys
logs, saved = float(sys.argv[1]), float(sys.argv[2])
j = json.load(open(sys.argv[4]))
print(json.dumps({'kind': 'localize', 'submaps': j['submaps'], 'map_features': j['map_features'], 'scans': j['scans'],
                  'cpu_s_logs': logs, 'cpu_s_saved_map': saved, 'cpu_ratio': logs / saved,
                  'same_trajectory': sys.argv[3] == 'true', 'localized': j['localized']}))" \
  "$(cpu_of "$work/t_logs")" "$(cpu_of "$work/t_saved")" "$same" "$work/saved.json" >>"$OUT"

python3 - "$OUT" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print("| R | features | file B/feature | memory B/feature | build map [s] | save [s] | load [s] | load per 1e6 [s] | 5-scan eval CPU: build / load [s] | ratio |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    if r["kind"] != "map": continue
    print(f"| {r['submaps']} | {r['features']:,} | {r['file_bytes_per_feature']:.1f} | {r['memory_bytes_per_feature']:.0f} | "
          f"{r['map_build_s']:.1f} | {r['save_s']:.2f} | {r['load_s']:.2f} | {r['load_s_per_1e6_features']:.2f} | "
          f"{r['eval5_cpu_building_s']:.1f} / {r['eval5_cpu_loading_s']:.2f} | {r['eval5_cpu_ratio']:.0f}x |")
print()
print("| fsync every | scans | scans/s |")
print("|---|---|---|")
for r in rows:
    if r["kind"] == "append": print(f"| {r['sync_every']} | {r['scans']} | {r['scans_per_s']:.0f} |")
print()
print("| building (R = 15) | scans | per-scan trace identical | success | map built [s] | map loaded [s] |")
print("|---|---|---|---|---|---|")
for r in rows:
    if r["kind"] == "identity":
        print(f"| {r['building']} | {r['scans']} | {r['trace_identical']} | {r['success']} | {r['map_build_s']:.1f} | {r['map_load_s']:.2f} |")
for r in rows:
    if r["kind"] == "localize":
        print(f"\nlocalize {r['scans']} scans, {r['submaps']} submaps ({r['map_features']:,} features): CPU {r['cpu_s_logs']:.1f} s "
              f"from the logs, {r['cpu_s_saved_map']:.2f} s from the saved map ({r['cpu_ratio']:.0f}x); same trajectory: {r['same_trajectory']}")
EOF
