#!/usr/bin/env bash
# Installs what is missing, builds, and runs the main job on the built-in
# default: for now, ingestion of the shared DFC2019 sample (or of a DFC2019
# root given as the first argument). Output goes to ./out/ (or $2).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
ROOT=${1:-../shared/data/dfc2019}
OUT=${2:-out}
if [ ! -d "$ROOT" ]; then
  echo "demo: no DFC2019 root at '$ROOT'; pass one as the first argument" >&2
  exit 1
fi
mkdir -p "$OUT"
./build/bin/skyfall ingest "$ROOT" --out "$OUT" --json > "$OUT/ingest_summary.json"
echo "demo: catalogs under $OUT/<AOI>/aoi.json, summary in $OUT/ingest_summary.json"
