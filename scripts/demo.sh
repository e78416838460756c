#!/usr/bin/env bash
# Installs what is missing, builds, and runs the main job on the built-in
# default scene: a synthetic satellite city written by `skyfall synth`, then
# ingested like real data. Give a DFC2019 root as the first argument to run on
# real data instead (e.g. ../shared/data/dfc2019). Output goes to ./out/ (or $2).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
OUT=${2:-out}
mkdir -p "$OUT"
if [ $# -ge 1 ]; then
  ROOT=$1
  if [ ! -d "$ROOT" ]; then
    echo "demo: no DFC2019 root at '$ROOT'" >&2
    exit 1
  fi
else
  ROOT="$OUT/synthetic-city"
  ./build/bin/skyfall synth --out "$ROOT"
fi
./build/bin/skyfall ingest "$ROOT" --out "$OUT/catalogs" --json > "$OUT/ingest_summary.json"
echo "demo: catalogs under $OUT/catalogs/<AOI>/aoi.json, summary in $OUT/ingest_summary.json"
