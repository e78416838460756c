#!/usr/bin/env bash
# Installs what is missing, builds, and runs every test (unit + integration on
# ../shared/data). This is what CI runs.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
BUILD_DIR=${SKYFALL_BUILD_DIR:-build}
cd "$BUILD_DIR"
ctest --output-on-failure --parallel "$(nproc)" --timeout 1200
