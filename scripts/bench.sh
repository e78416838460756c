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
