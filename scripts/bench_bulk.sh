#!/usr/bin/env bash
# Bulk DFC-style input run unattended: a tree of N scattered AOIs (N cities,
# 16 by default, each a 256 m synthetic AOI about 5 km from the next), run
# once with the defaults and once more unchanged. Prints and writes
# OUT/bench_bulk.json: both runs' exit codes and times, throughput in AOIs
# per hour, whether run_summary.json and report.html list every city, and
# each city's DSM MAE. (The tree of adjacent AOIs, one city, is
# scripts/bench_city.sh.)
#
# Usage: scripts/bench_bulk.sh [OUT]      (default OUT=out/bench_bulk)
#   SKYFALL_BULK_AOIS     AOIs (and cities), default 16
#   SKYFALL_BULK_SIZE_M   AOI side [m], default 256
#   SKYFALL_BIN, SKYFALL_RUN_ARGS as for the other benchmarks (bench_env.sh)
# The tree is made once and kept; a finished first run is reused (delete
# OUT/run to measure again); the unchanged rerun is measured every time.
set -euo pipefail
cd "$(dirname "$0")/.."
case "${1:-}" in -*) echo "bench_bulk: unknown option $1 (usage: scripts/bench_bulk.sh [OUT])" >&2; exit 2 ;; esac
OUT=${1:-out/bench_bulk}
AOIS=${SKYFALL_BULK_AOIS:-16}
SIZE=${SKYFALL_BULK_SIZE_M:-256}
source scripts/bench_env.sh
mkdir -p "$OUT"
root="$OUT/tree" run="$OUT/run"
for k in $(seq 1 "$AOIS"); do
  name=$(printf "BLK_%03d" "$k")
  [ -f "$root/synth_report_$name.json" ] && continue
  # A 4-wide grid of cities 0.05 deg (about 5 km) apart, each its own seed.
  lat=$(python3 -c "print(30.3 + 0.05 * (($k - 1) // 4))")
  lon=$(python3 -c "print(-81.7 + 0.05 * (($k - 1) % 4))")
  echo "bench_bulk: synthesizing $name at $lat, $lon ..." >&2
  "$B" -q synth --out "$root" --aoi "$name" --seed "$k" --size-m "$SIZE" --lat "$lat" --lon "$lon"
  mv "$root/synth_report.json" "$root/synth_report_$name.json"
done

timed_run() {  # timed_run LOG: runs skyfall on the tree, prints "EXIT SECONDS"
  local start rc=0
  start=$(date +%s.%N)
  "$B" run "$root" --out "$run" "${RUN_ARGS[@]}" 2> "$1" || rc=$?
  awk -v a="$(date +%s.%N)" -v b="$start" -v rc="$rc" 'BEGIN { printf "%d %.1f\n", rc, a - b }'
}
if [ -f "$run/first_run" ]; then
  echo "bench_bulk: reusing the finished first run in $run" >&2
else
  echo "bench_bulk: first run over $AOIS AOIs (log: $run.log) ..." >&2
  first=$(timed_run "$run.log")
  echo "$first" > "$run/first_run"
fi
echo "bench_bulk: unchanged rerun ..." >&2
timed_run "$run.rerun.log" > "$OUT/rerun"

python3 - "$OUT" "$run" "$AOIS" "$SIZE" <<'PY'
import json, os, sys
out, run, aois, size_m = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
first_rc, first_s = open(os.path.join(run, "first_run")).read().split()
rerun_rc, rerun_s = open(os.path.join(out, "rerun")).read().split()
summary = json.load(open(os.path.join(run, "run_summary.json")))
page = open(os.path.join(run, "report.html")).read()
cities = [c["city"] for c in summary["cities"]]
mae = {}
for c in summary["cities"]:
    if os.path.exists(c.get("report", "")):
        for d in json.load(open(c["report"])).get("dsm", []):
            mae[d["aoi"]] = d["mae_m"]
doc = {
    "aois": aois, "aoi_side_m": size_m, "cores": os.cpu_count(), "cities": len(cities),
    "first_run": {"exit_code": int(first_rc), "seconds": float(first_s)},
    "rerun_unchanged": {"exit_code": int(rerun_rc), "seconds": float(rerun_s),
                        "cities_unchanged": sum(1 for c in summary["cities"] if c.get("unchanged"))},
    "aois_per_hour": aois / (float(first_s) / 3600.0),
    "summary_lists_every_city": len(cities) == aois,
    "report_page_lists_every_city": all(c in page for c in cities),
    "dsm_mae_m": mae,
}
tmp = os.path.join(out, "bench_bulk.json.tmp")
json.dump(doc, open(tmp, "w"), indent=1)
os.replace(tmp, os.path.join(out, "bench_bulk.json"))
print(f"bulk: {aois} AOIs in {len(cities)} cities; first run exit {first_rc} in {float(first_s):.0f} s "
      f"({doc['aois_per_hour']:.1f} AOIs per hour); unchanged rerun exit {rerun_rc} in {float(rerun_s):.1f} s "
      f"({doc['rerun_unchanged']['cities_unchanged']} cities unchanged); summary lists every city: "
      f"{doc['summary_lists_every_city']}, report page: {doc['report_page_lists_every_city']}")
print("bench_bulk: wrote " + os.path.join(out, "bench_bulk.json"))
PY
