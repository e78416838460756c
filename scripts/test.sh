#!/usr/bin/env bash
# Installs what is missing, builds, and runs every test (unit + integration on
# ../shared/data). This is what CI runs.
#   scripts/test.sh              Release build in build/
#   scripts/test.sh --sanitize   ASan + UBSan build in build-asan/, same tests
set -euo pipefail
cd "$(dirname "$0")/.."
extra=()
if [ "${1:-}" = "--sanitize" ]; then
  export SKYFALL_BUILD_DIR=${SKYFALL_BUILD_DIR:-build-asan}
  extra=(-DSKYFALL_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo)
  # Leaks are reported at exit; UBSan stops at its first report.
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
fi
bash scripts/setup.sh
bash scripts/build.sh "${extra[@]}"
BUILD_DIR=${SKYFALL_BUILD_DIR:-build}
cd "$BUILD_DIR"
ctest --output-on-failure --parallel "$(nproc)" --timeout 1200
