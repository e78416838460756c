#!/usr/bin/env bash
# A city run end to end, as users run one: `skyfall synth` makes an N x N km
# city of adjacent 256 m AOIs (4 x 4 for 1 km, 8 x 8 for 2 km), `skyfall run`
# reconstructs it with the defaults and --3dtiles, and this script prints and
# writes OUT/bench_city.json: time (whole, per km^2, per stage), peak memory
# of the tile processes and of the merge and the export, Gaussians per LOD
# level, the tileset's size and depth, the city DSM's MAE against the truth,
# the mean MAE of the tiles' own reconstructions over their cores (each
# tile rasterized alone, before the merge), the MAE within 10 m of an
# interior tile border, the seam metric per interior border, and the steps of
# the DSM's error across the borders between AOIs where the truth is smooth.
#
# Usage: scripts/bench_city.sh [--km N] [--slurm] [OUT]   (default: --km 1, OUT=out/bench_city_<N>km)
#   --slurm   run through `--executor slurm` on a one-node cluster started on
#             this machine (scripts/slurm_local.sh, in OUT/cluster; one CPU
#             per tile job, as the local executor gives each of its two
#             tiles): OUT/run_slurm and OUT/bench_city_slurm.json, whose DSM
#             figures should equal the local run's
#   SKYFALL_BIN, SKYFALL_RUN_ARGS as for the other benchmarks (bench_env.sh)
#   SKYFALL_CITY_BLOCK_M   AOI side [m], default 256
#   SKYFALL_SYNTH_ARGS     further `skyfall synth` options for the city, e.g.
#                          "--rpc-bias-px 10 --views-per-aoi 8" (used when the city is made)
# The synthetic city is made once (about 7 min for 1 km on 2 cores) and kept.
# A finished run is reused (delete OUT/run to measure again). A run can be
# stopped part way (kill the script's process group: TERM or INT) and
# finished by calling the script again: each sitting's time is recorded in
# OUT/run.sittings, the run's time is their sum, and the JSON says how many
# sittings it took. That sum is an upper bound: the tiles a stop cut short
# are redone. A run interrupted without a record (killed outright) resumes
# too, and the JSON then says `resumed` (its time is not a whole run).
set -euo pipefail
cd "$(dirname "$0")/.."
KM=1
OUT=
EXECUTOR=local
while [ $# -gt 0 ]; do
  case $1 in
    --km) KM=$2; shift 2 ;;
    --km=*) KM=${1#--km=}; shift ;;
    --slurm) EXECUTOR=slurm; shift ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    -*) echo "bench_city: unknown option $1" >&2; exit 2 ;;
    *) OUT=$1; shift ;;
  esac
done
BLOCK=${SKYFALL_CITY_BLOCK_M:-256}
N=$(python3 -c "import sys; n = round(float(sys.argv[1]) * 1000 / float(sys.argv[2])); print(n if n >= 1 else '')" "$KM" "$BLOCK")
[ -n "$N" ] || { echo "bench_city: --km $KM is less than one ${BLOCK} m AOI" >&2; exit 2; }
OUT=${OUT:-out/bench_city_${KM}km}
source scripts/bench_env.sh
mkdir -p "$OUT"
root="$OUT/city" run="$OUT/run" figures_json=bench_city.json
EXEC_ARGS=()
if [ "$EXECUTOR" = slurm ]; then
  run="$OUT/run_slurm" figures_json=bench_city_slurm.json
  EXEC_ARGS=(--executor slurm --slurm-cpus 1)
fi
if [ ! -f "$root/synth_report.json" ]; then
  echo "bench_city: synthesizing a city of ${N} x ${N} AOIs of ${BLOCK} m ..." >&2
  read -r -a SYNTH_ARGS <<< "${SKYFALL_SYNTH_ARGS:-}"
  "$B" -q synth --out "$root" --size-m "$BLOCK" --blocks-x "$N" --blocks-y "$N" --aoi CTY_001 "${SYNTH_ARGS[@]}"
fi
if [ -f "$run/wall_seconds" ]; then
  echo "bench_city: reusing the finished run in $run" >&2
else
  sittings="$run.sittings"
  # Time spent before the first recorded sitting is unknown.
  resumed=false
  [ -d "$run" ] && [ ! -s "$sittings" ] && resumed=true
  [ -d "$run" ] || rm -f "$sittings" "$run.log"
  if [ "$EXECUTOR" = slurm ]; then
    bash scripts/slurm_local.sh start "$OUT/cluster" >&2
    trap 'bash scripts/slurm_local.sh stop "$OUT/cluster" >/dev/null 2>&1 || true' EXIT
    export SLURM_CONF="$(cd "$OUT/cluster" && pwd)/slurm.conf"
  fi
  echo "bench_city: skyfall run on ${N} x ${N} AOIs, $EXECUTOR executor (log: $run.log) ..." >&2
  start=$(date +%s.%N)
  record_sitting() { awk -v a="$(date +%s.%N)" -v b="$start" 'BEGIN { printf "%.1f\n", a - b }' >> "$sittings"; }
  trap 'record_sitting; echo "bench_city: stopped; run the same command again to finish the run" >&2; exit 143' TERM INT
  rc=0
  "$B" run "$root" --out "$run" --3dtiles "${EXEC_ARGS[@]}" "${RUN_ARGS[@]}" 2>> "$run.log" || rc=$?
  trap - TERM INT
  record_sitting
  [ "$rc" -eq 0 ] || { echo "bench_city: skyfall run failed (exit $rc); see $run.log" >&2; exit 1; }
  awk '{ s += $1 } END { printf "%.1f\n", s }' "$sittings" > "$run/wall_seconds"
  wc -l < "$sittings" | tr -d ' ' > "$run/sittings"
  echo "$resumed" > "$run/resumed"
fi

# Each tile's own reconstruction, rasterized alone on the grid of every AOI
# its core touches and compared with that AOI's truth (the single-tile
# figures the city's are judged against).
# (Debian's python3: GDAL and NumPy come with python3-gdal.)
/usr/bin/python3 scripts/bench_city_figures.py jobs "$root" "$run" > "$OUT/single_tile_jobs.txt"
while read -r id dir aoi epsg; do
  dest="$OUT/single_tile/$id/$aoi"
  [ -f "$dest/compare/report.json" ] && continue
  mkdir -p "$dest"
  truth="$root/Track3-Truth/$aoi"
  # The tile's DSM surface (TileSurfacePath): training's surface when it kept one.
  scene="$dir/splat/surface.ply"; [ -f "$scene" ] || scene="$dir/splat/scene.ply"
  "$B" -q dsm export --scene "$scene" --frame "$dir/aoi.json" --grid "${truth}_DSM.txt" \
    --out "$dest/dsm.tmp.tif" && mv "$dest/dsm.tmp.tif" "$dest/dsm.tif"
  "$B" -q dsm compare --pred "$dest/dsm.tif" --gt "${truth}_DSM.tif" --gt-txt "${truth}_DSM.txt" --epsg "$epsg" \
    --cls "${truth}_CLS.tif" --out "$dest/compare"
done < "$OUT/single_tile_jobs.txt"

# The merge and the 3D Tiles export alone, each in its own process, for
# their own peak memory (the run's figures are one process's high-water
# mark, which the products stage between them may have set).
city_dir=$(dirname "$(ls -d "$run"/*/tiles | head -1)")
for step in merge export; do
  [ -f "$OUT/$step.time" ] && [ "$OUT/$step.time" -nt "$run/wall_seconds" ] && continue
  rm -rf "$OUT/${step}_alone"
  if [ "$step" = merge ]; then
    /usr/bin/time -v "$B" -q merge --tiles "$city_dir/tiles" --out "$OUT/merge_alone" 2> "$OUT/$step.time"
  else
    /usr/bin/time -v "$B" -q export 3dtiles --scene "$city_dir/scene" --out "$OUT/export_alone" 2> "$OUT/$step.time"
  fi
done

# The viewer on the city's tileset (headless Chromium): the whole city, then a street.
if [ -d "$city_dir/3dtiles" ] && [ ! -f "$OUT/viewer/check.json" ]; then
  port=$((20000 + $$ % 20000))
  "$B" -q view "$run" --port "$port" > "$OUT/view.log" 2>&1 &
  server=$!
  # Until the server answers (it reads the run first: seconds on a 2 km city).
  for _ in $(seq 120); do
    python3 -c "import urllib.request, sys; urllib.request.urlopen(sys.argv[1], timeout=2)" \
      "http://127.0.0.1:$port/view/index.html" 2>/dev/null && break
    kill -0 "$server" 2>/dev/null || break
    sleep 1
  done
  mkdir -p "$OUT/viewer"
  node web/check_city_view.mjs "http://127.0.0.1:$port/view/index.html" "$OUT/viewer" > "$OUT/viewer/check.tmp" \
    && mv "$OUT/viewer/check.tmp" "$OUT/viewer/check.json" || echo "bench_city: the viewer check failed ($OUT/viewer/check.tmp)" >&2
  kill "$server" 2>/dev/null || true
  pkill -P "$server" 2>/dev/null || true
fi

/usr/bin/python3 scripts/bench_city_figures.py figures "$KM" "$N" "$BLOCK" "$root" "$run" "$OUT" "$figures_json" "$EXECUTOR"
