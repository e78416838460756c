#!/usr/bin/env bash
# Speed figures (never timed unit tests): prints the wall time of the stages
# that have targets. Usage: scripts/bench.sh [repeats]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh >/dev/null
REPEATS=${1:-3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
times=()
for i in $(seq 1 "$REPEATS"); do
  start=$EPOCHREALTIME
  ./build/bin/skyfall -q synth --out "$tmp/synth_$i"
  times+=("$(awk -v a="$start" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.2f", b - a }')")
done
sorted=$(printf '%s\n' "${times[@]}" | sort -n)
echo "synth default scene (256 m, 12 views, $(nproc) cores): runs [${times[*]}] s"
echo "synth default scene: min $(echo "$sorted" | head -1) s, median $(echo "$sorted" | sed -n "$(( (REPEATS + 1) / 2 ))p") s (target < 15 s)"
start=$EPOCHREALTIME
./build/bin/skyfall -q ingest "$tmp/synth_1" --out "$tmp/catalogs" >/dev/null
echo "ingest of the default scene: $(awk -v a="$start" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.2f", b - a }') s"

# SfM on the real JAX_068 sample (19 crops), target < 2 min.
JAX=../shared/data/dfc2019
if [ -d "$JAX" ]; then
  ./build/bin/skyfall -q ingest "$JAX" --out "$tmp/jax" --aoi JAX_068 >/dev/null
  start=$EPOCHREALTIME
  ./build/bin/skyfall -q sfm --aoi "$tmp/jax/JAX_068/aoi.json" --out "$tmp/jax/sfm" --no-colmap-images || true
  echo "sfm JAX_068 (19 images): $(awk -v a="$start" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f", b - a }') s (target < 120 s)"
  grep -E '"(ba_median_reproj_px_(before|after)|dlt_max_error_px|num_points|num_images_used)"' "$tmp/jax/sfm/sfm_report.json" | sed 's/^ */  /'
else
  echo "sfm JAX_068: skipped, no $JAX"
fi

# Rasterizer: forward and forward+backward, 100k Gaussians, 512x384 (target fwd+bwd <= 130 ms).
./build/bin/rasterizer_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true 2>/dev/null \
  | grep -E "^BM_.*(median|mean)"
