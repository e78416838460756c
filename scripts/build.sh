#!/usr/bin/env bash
# Release build; the binary ends up at build/bin/skyfall.
# Usage: scripts/build.sh [extra cmake -D options]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${SKYFALL_BUILD_DIR:-build}
generator=()
if command -v ninja >/dev/null 2>&1; then generator=(-G Ninja); fi
# A configure that failed (say, before setup.sh installed the packages)
# leaves a cache but no build files: configure again instead of wedging.
if [ ! -f "$BUILD_DIR/CMakeCache.txt" ] || { [ ! -f "$BUILD_DIR/build.ninja" ] && [ ! -f "$BUILD_DIR/Makefile" ]; }; then
  cmake -S . -B "$BUILD_DIR" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release "$@"
elif [ $# -gt 0 ]; then
  cmake "$BUILD_DIR" "$@"
fi
# Two cores, ~1.5 GiB per compiler process at most: -j follows the core count.
cmake --build "$BUILD_DIR" --parallel "$(nproc)"
echo "build: $BUILD_DIR/bin/skyfall"
