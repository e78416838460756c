#!/usr/bin/env bash
# Installs what is missing, builds, and runs every test (unit + integration on
# ../shared/data). This is what CI runs.
#   scripts/test.sh              Release build in build/, every test; then the
#                                sanitizer subset (label `sanitizer_subset`,
#                                listed in CMakeLists.txt) with ASan + UBSan
#                                in build-asan-subset/ (about 3 more minutes)
#   scripts/test.sh --no-sanitizer-subset   the Release tests only
#   scripts/test.sh --sanitize   ASan + UBSan build in build-asan/, every test
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:-all}
case "$mode" in
  all | --sanitize | --no-sanitizer-subset) ;;
  *) echo "usage: scripts/test.sh [--sanitize | --no-sanitizer-subset]" >&2; exit 2 ;;
esac

# Leaks are reported at exit; UBSan stops at its first report.
sanitizer_env() {
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
}

bash scripts/setup.sh
# The scripts' own tests (seconds): the README results table's writer, and
# bench_city.sh's seam figures (Debian's python3, which has GDAL and NumPy).
python3 scripts/readme_results_test.py
/usr/bin/python3 scripts/bench_city_figures_test.py
if [ "$mode" = "--sanitize" ]; then
  sanitizer_env
  export SKYFALL_BUILD_DIR=${SKYFALL_BUILD_DIR:-build-asan}
  bash scripts/build.sh -DSKYFALL_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo
  (cd "$SKYFALL_BUILD_DIR" && ctest --output-on-failure --parallel "$(nproc)" --timeout 1200)
  exit 0
fi

# A build variant that nothing else configures rots unseen: configure every
# one (seconds each; the one without tests once failed on a test-only
# property, which also broke scripts/fuzz.sh). The fuzz variant is clang's.
cmake -S . -B build-variant-notests -DSKYFALL_BUILD_TESTS=OFF >/dev/null
cmake -S . -B build-variant-sanitize -DSKYFALL_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
CC=clang CXX=clang++ cmake -S . -B build-variant-fuzz -DSKYFALL_FUZZ=ON -DSKYFALL_BUILD_TESTS=OFF \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null

bash scripts/build.sh
(cd "${SKYFALL_BUILD_DIR:-build}" && ctest --output-on-failure --parallel "$(nproc)" --timeout 1200)
[ "$mode" = "--no-sanitizer-subset" ] && exit 0

# -O1 with line tables builds in half the time of RelWithDebInfo and keeps
# the sanitizers' stack traces readable.
echo "sanitizer subset (ASan + UBSan): building"
sanitizer_env
subset_dir=build-asan-subset
if [ ! -f "$subset_dir/build.ninja" ] && [ ! -f "$subset_dir/Makefile" ]; then
  generator=()
  if command -v ninja >/dev/null 2>&1; then generator=(-G Ninja); fi
  cmake -S . -B "$subset_dir" "${generator[@]}" -DCMAKE_BUILD_TYPE=None "-DCMAKE_CXX_FLAGS=-O1 -g1" \
    -DSKYFALL_SANITIZE=ON >/dev/null
fi
cmake --build "$subset_dir" --parallel "$(nproc)" --target sanitizer_subset
(cd "$subset_dir" && ctest --output-on-failure --parallel "$(nproc)" --timeout 1200 -L '^sanitizer_subset$')
