#!/usr/bin/env bash
# Installs what is missing, builds, and runs the main job on the built-in
# default scene: a synthetic satellite city written by `skyfall synth`, then
# ingest -> sfm -> splat train -> dsm export -> dsm compare against its truth.
# Give a DFC2019 root as the first argument to run on real data instead
# (e.g. ../shared/data/dfc2019). Output goes to ./out/ (or $2).
# Until `skyfall run` exists (tiling issue) this script chains the stages.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
OUT=${2:-out}
ITERATIONS=${SKYFALL_DEMO_ITERATIONS:-1000}
B=./build/bin/skyfall
mkdir -p "$OUT"
if [ $# -ge 1 ]; then
  ROOT=$1
  if [ ! -d "$ROOT" ]; then
    echo "demo: no DFC2019 root at '$ROOT'" >&2
    exit 1
  fi
else
  ROOT="$OUT/synthetic-city"
  $B synth --out "$ROOT"
fi
$B ingest "$ROOT" --out "$OUT/catalogs" --json > "$OUT/ingest_summary.json"
for catalog in "$OUT"/catalogs/*/aoi.json; do
  AOI_DIR=$(dirname "$catalog")
  AOI=$(basename "$AOI_DIR")
  $B sfm --aoi "$catalog" --out "$AOI_DIR/sfm" --no-colmap-images
  $B splat train --sfm "$AOI_DIR/sfm" --out "$AOI_DIR/splat" --iterations "$ITERATIONS" --resolution 2
  $B dsm export --scene "$AOI_DIR/splat/scene.ply" --frame "$catalog" --out "$AOI_DIR/dsm.tif"
  TRUTH="$ROOT/Track3-Truth/${AOI}"
  if [ -f "${TRUTH}_DSM.tif" ] && [ -f "${TRUTH}_DSM.txt" ]; then
    EPSG=$(grep -o '"epsg": [0-9]*' "$catalog" | head -1 | grep -o '[0-9]*$')
    CLS=()
    [ -f "${TRUTH}_CLS.tif" ] && CLS=(--cls "${TRUTH}_CLS.tif")
    $B dsm compare --pred "$AOI_DIR/dsm.tif" --gt "${TRUTH}_DSM.tif" --gt-txt "${TRUTH}_DSM.txt" \
      --epsg "$EPSG" "${CLS[@]}" --out "$AOI_DIR/dsm_compare"
  fi
done
echo "demo: results under $OUT/catalogs/<AOI>/ (sfm/, splat/scene.ply, dsm.tif, dsm_compare/)"
