#!/usr/bin/env bash
# Installs what is missing, builds, and runs the main job, `skyfall run`, on
# the built-in default scene: a synthetic satellite city written by
# `skyfall synth` (ingest -> tile -> per-tile SfM, dense heights, splat training -> merge
# with LOD -> DSM export and comparison with the city's truth).
# Give a DFC2019 root as the first argument to run on real data instead
# (e.g. ../shared/data/dfc2019). Output goes to ./out/ (or $2). Reruns resume.
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
  [ -f "$ROOT/synth_report.json" ] || $B synth --out "$ROOT"
fi
$B run "$ROOT" --out "$OUT" --iterations "$ITERATIONS" --resolution 2
echo "demo: results under $OUT/<city>/ (scene/scene.ply, scene/lod_*.ply, run_report.json) and $OUT/<AOI>/ (dsm.tif, dsm_compare/)"
