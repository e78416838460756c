#!/usr/bin/env bash
# How the tiled pipeline scales with area: synthetic cities of 1, 2 and 4
# tiles of 256 m (1x1, 2x1, 2x2 blocks) and the paper-style multi-block city
# of 1 km x 512 m (two adjacent 512 m AOIs, 8 tiles). Prints time per tile,
# merge time, peak memory and total time per city, from the run reports.
# Usage: scripts/bench_scale.sh [OUT] ; SKYFALL_SCALE_ITERATIONS (default 300),
# SKYFALL_SCALE_CASES (default "1 2 4 8").
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x build/bin/skyfall ] || bash scripts/build.sh
OUT=${1:-out/bench_scale}
ITER=${SKYFALL_SCALE_ITERATIONS:-300}
B=./build/bin/skyfall
mkdir -p "$OUT"
for n in ${SKYFALL_SCALE_CASES:-1 2 4 8}; do
  case $n in
    1) args="--size-m 256 --blocks-x 1 --blocks-y 1" ;;
    2) args="--size-m 256 --blocks-x 2 --blocks-y 1" ;;
    4) args="--size-m 256 --blocks-x 2 --blocks-y 2" ;;
    8) args="--size-m 512 --blocks-x 2 --blocks-y 1" ;;
    *) echo "bench_scale: unknown case $n" >&2; exit 1 ;;
  esac
  root="$OUT/city$n"
  [ -f "$root/synth_report.json" ] || $B -q synth --out "$root" $args --aoi "SC${n}_001"
  start=$(date +%s.%N)
  $B -q run "$root" --out "$OUT/run$n" --tile-m 256 --overlap-m 32 --iterations "$ITER" --resolution 2
  end=$(date +%s.%N)
  python3 - "$OUT/run$n" "$n" "$start" "$end" <<'PY'
import glob, json, sys
out, n, start, end = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
for path in glob.glob(out + "/*/run_report.json"):
    r = json.load(open(path))
    tiles = [t for t in r["tiles"] if t.get("status") == "ok"]
    secs = [t["tile_seconds"] for t in tiles]
    merge = next(s["seconds"] for s in r["stages"] if s["stage"] == "merge")
    tiles_stage = next(s["seconds"] for s in r["stages"] if s["stage"] == "tiles")
    mae = ", ".join(f'{d["aoi"]} {d["mae_m"]:.2f}' for d in r["dsm"])
    print(f"tiles={n} ok={len(tiles)} parallel={r['options']['parallel_tiles']} "
          f"tile_s mean={sum(secs)/max(len(secs),1):.1f} max={max(secs, default=0):.1f} "
          f"tiles_stage_s={tiles_stage:.1f} merge_s={merge:.2f} peak_tile_rss_mb={r['peak_tile_rss_mb']:.0f} "
          f"gaussians={int(r['merge']['gaussians'])} dup_removed={int(r['merge']['duplicates_removed'])} "
          f"holes_filled={int(r['merge']['holes_filled'])} seam_ratio={r['seam']['ratio']} "
          f"total_s={end-start:.1f} dsm_mae_m=[{mae}]")
PY
done
