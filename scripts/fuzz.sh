#!/usr/bin/env bash
# libFuzzer on every parser of outside input (fuzz/fuzz_*.cpp).
# Usage: scripts/fuzz.sh [SECONDS_PER_TARGET (default 60)] [TARGET...]
# Builds build-fuzz with clang (libFuzzer + ASan + UBSan), runs each target
# for the given time on its corpus fuzz/corpus/<name>/, then merges the
# corpus down to the inputs that add coverage (commit it: the test suite
# replays it). Crashes, leaks and timeouts are saved under
# build-fuzz/artifacts/<name>/; a summary goes to build-fuzz/fuzz_results.json.
# Exit code 1 when any target found one.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(rpc dsm_txt catalogs cameras ply reports)
BUILD=${SKYFALL_FUZZ_BUILD_DIR:-build-fuzz}

if ! command -v clang++ >/dev/null 2>&1 || ! ls /usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a >/dev/null 2>&1; then
  echo "fuzz: installing clang and its libFuzzer runtime"
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends clang libclang-rt-14-dev >/dev/null
fi
if [ ! -f "$BUILD/build.ninja" ]; then
  CC=clang CXX=clang++ cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DSKYFALL_FUZZ=ON -DSKYFALL_BUILD_TESTS=OFF
fi
cmake --build "$BUILD" --parallel "$(nproc)" --target "${targets[@]/#/fuzz_}"

failed=0
results="["
for t in "${targets[@]}"; do
  corpus=fuzz/corpus/$t
  artifacts=$BUILD/artifacts/$t/
  mkdir -p "$artifacts" "$corpus"
  log=$BUILD/fuzz_$t.log
  echo "fuzz: $t for ${seconds} s"
  rc=0
  "$BUILD/bin/fuzz_$t" "$corpus" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -artifact_prefix="$artifacts" -print_final_stats=1 >"$log" 2>&1 || rc=$?
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  # Keep only the inputs that add coverage.
  rm -rf "$corpus.min" && mkdir -p "$corpus.min"
  "$BUILD/bin/fuzz_$t" -merge=1 "$corpus.min" "$corpus" >/dev/null 2>&1 && rm -rf "$corpus" && mv "$corpus.min" "$corpus"
  rm -rf "$corpus.min"
  inputs=$(find "$corpus" -type f | wc -l)
  status=ok
  if [ "$rc" -ne 0 ]; then status="failed (exit $rc, see $log and $artifacts)"; failed=1; fi
  echo "fuzz: $t: $status, $runs executions, corpus $inputs inputs"
  results+="{\"target\": \"$t\", \"seconds\": $seconds, \"executions\": ${runs:-0}, \"corpus_inputs\": $inputs, \"exit_code\": $rc},"
done
echo "${results%,}]" >"$BUILD/fuzz_results.json"
echo "fuzz: summary in $BUILD/fuzz_results.json"
exit $failed
