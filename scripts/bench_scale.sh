#!/usr/bin/env bash
# How the tiled pipeline scales with area: synthetic cities of 1, 2 and 4
# AOIs of SIZE x SIZE m (1x1, 2x1, 2x2 blocks, one tile each) and 8 tiles
# (two adjacent AOIs of 2 SIZE, the paper-style multi-block city). Prints
# time per tile, merge time, peak memory and total time per city, from the
# run reports, and the ratio of each city's time to the 1-tile city's
# against its ratio of area (the target: 4x the area in at most 4.4x the
# time, at equal cores). Writes OUT/bench_scale.json.
#
# Usage: scripts/bench_scale.sh [OUT]
#   SKYFALL_SCALE_CASES       tiles per city, default "1 2 4 8"
#   SKYFALL_SCALE_SIZE_M      AOI (and tile core) side [m], default 256
#   SKYFALL_SCALE_ITERATIONS  training steps per tile, default 300
#   SKYFALL_SCALE_OVERLAP_M   tile overlap margin [m], default 8 (the product default)
#   SKYFALL_SCALE_REPEATS     runs per city, default 3: whole runs on 2 cores
#                             spread by about 10%, so one run per city moves
#                             a time ratio by +-0.4; the ratios use each
#                             city's median time (all times are in the JSON)
#   SKYFALL_BIN, SKYFALL_RUN_ARGS as for the other benchmarks (bench_env.sh)
# Runs are interleaved (every city once, then again) so that a slow spell of
# the machine does not fall on one city. Reruns reuse finished runs (delete
# OUT/runN or OUT/runN.rK to measure again).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/bench_scale}
ITER=${SKYFALL_SCALE_ITERATIONS:-300}
REPEATS=${SKYFALL_SCALE_REPEATS:-3}
SIZE=${SKYFALL_SCALE_SIZE_M:-256}
OVERLAP=${SKYFALL_SCALE_OVERLAP_M:-8}
source scripts/bench_env.sh
mkdir -p "$OUT"
CASES=${SKYFALL_SCALE_CASES:-1 2 4 8}
for n in $CASES; do
  case $n in
    1) args="--size-m $SIZE --blocks-x 1 --blocks-y 1" ;;
    2) args="--size-m $SIZE --blocks-x 2 --blocks-y 1" ;;
    4) args="--size-m $SIZE --blocks-x 2 --blocks-y 2" ;;
    8) args="--size-m $((2 * SIZE)) --blocks-x 2 --blocks-y 1" ;;
    *) echo "bench_scale: unknown case $n (1, 2, 4 or 8)" >&2; exit 1 ;;
  esac
  root="$OUT/city$n"
  # shellcheck disable=SC2086
  [ -f "$root/synth_report.json" ] || "$B" -q synth --out "$root" $args --aoi "SC${n}_001"
done
# Run k of city n lands in OUT/runN (k = 1) or OUT/runN.rK.
for k in $(seq 1 "$REPEATS"); do
  for n in $CASES; do
    run="$OUT/run$n"
    [ "$k" -gt 1 ] && run="$OUT/run$n.r$k"
    if [ -f "$run/run_summary.json" ] && [ -f "$run/wall_seconds" ]; then
      echo "bench_scale: $n tiles, run $k: reusing the finished run" >&2
      continue
    fi
    echo "bench_scale: $n tile(s), run $k of $REPEATS ..." >&2
    start=$(date +%s.%N)
    "$B" -q run "$OUT/city$n" --out "$run" --tile-m "$SIZE" --overlap-m "$OVERLAP" --iterations "$ITER" --resolution 2 \
      "${RUN_ARGS[@]}" 2> "$run.log"
    awk -v a="$(date +%s.%N)" -v b="$start" 'BEGIN { printf "%.1f\n", a - b }' > "$run/wall_seconds"
  done
done

python3 - "$OUT" "$SIZE" "$ITER" "$CASES" "$OVERLAP" "$REPEATS" <<'PY'
import glob, json, os, statistics, sys
out, size_m, iters, cases = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4].split()
overlap_m, repeats = float(sys.argv[5]), int(sys.argv[6])
rows = []
for n in cases:
    run = os.path.join(out, "run" + n)
    if not os.path.exists(os.path.join(run, "wall_seconds")):
        continue
    # Tile, merge and DSM figures from the first run; the time from all.
    times = [float(open(os.path.join(r, "wall_seconds")).read())
             for r in [run] + [f"{run}.r{k}" for k in range(2, repeats + 1)]
             if os.path.exists(os.path.join(r, "wall_seconds"))]
    reports = [json.load(open(p)) for p in sorted(glob.glob(run + "/*/run_report.json"))]
    tiles = [t for r in reports for t in r["tiles"] if t.get("status") == "ok"]
    secs = [t["tile_seconds"] for t in tiles]
    def stage(r, name):
        return next((s["seconds"] for s in r["stages"] if s["stage"] == name), 0.0)
    rows.append({
        "tiles": int(n),
        "tiles_ok": len(tiles),
        "area_km2": int(n) * size_m * size_m / 1e6,  # every case is n tiles of size_m^2
        "total_s": statistics.median(times),  # median over the runs
        "total_s_runs": times,
        "tiles_stage_s": sum(stage(r, "tiles") for r in reports),
        "merge_s": sum(stage(r, "merge") for r in reports),
        "tile_s_mean": sum(secs) / max(len(secs), 1),
        "tile_s_max": max(secs, default=0.0),
        "peak_tile_rss_mb": max((r.get("peak_tile_rss_mb", 0) for r in reports), default=0),
        "dsm_mae_m": {d["aoi"]: d["mae_m"] for r in reports for d in r["dsm"]},
    })
base = next((r for r in rows if r["tiles"] == 1), None)
for r in rows:
    if base:
        r["area_ratio"] = r["area_km2"] / base["area_km2"]
        r["time_ratio"] = r["total_s"] / base["total_s"]
    print(f'tiles={r["tiles"]} ok={r["tiles_ok"]} area={r["area_km2"]:.3f} km2 total_s={r["total_s"]:.1f} '
          f'(median of {" ".join(f"{t:.1f}" for t in r["total_s_runs"])}) '
          f'tiles_stage_s={r["tiles_stage_s"]:.1f} merge_s={r["merge_s"]:.2f} tile_s mean={r["tile_s_mean"]:.1f} '
          f'max={r["tile_s_max"]:.1f} peak_tile_rss_mb={r["peak_tile_rss_mb"]:.0f}'
          + (f' area_ratio={r["area_ratio"]:.2f} time_ratio={r["time_ratio"]:.2f}' if base else ""))
# 4x the area: 1 -> 4 tiles (the 1-tile city has no tile overlap to process;
# every tile of the 4-tile one has the overlap margin on two sides) and 2 -> 8 tiles
# (overlap on both).
summary = {"size_m": size_m, "overlap_m": overlap_m, "iterations": iters, "repeats": repeats,
           "cores": os.cpu_count(), "cities": rows,
           "target_4x_area_max_ratio": 4.4, "time_ratio_4x_area": {}}
by_tiles = {r["tiles"]: r for r in rows}
for small, large in ((1, 4), (2, 8)):
    if small in by_tiles and large in by_tiles:
        ratio = by_tiles[large]["total_s"] / by_tiles[small]["total_s"]
        summary["time_ratio_4x_area"][f"{small}->{large}"] = ratio
        print(f'4x the area ({small} -> {large} tiles) took {ratio:.2f}x the time (median runs; target <= 4.4x)')
tmp = os.path.join(out, "bench_scale.json.tmp")
json.dump(summary, open(tmp, "w"), indent=1)
os.replace(tmp, os.path.join(out, "bench_scale.json"))
print("bench_scale: wrote " + os.path.join(out, "bench_scale.json"))
PY
