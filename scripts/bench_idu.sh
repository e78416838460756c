#!/usr/bin/env bash
# Synthesis-stage (IDU) benchmark: the whole pipeline (`skyfall run`
# defaults) without and with the curriculum IDU on the same reconstruction,
# then orbit views at 75, 60 and 45 deg elevation that no episode used,
# rendered before and after IDU and compared with the synthetic city's exact
# truth images (masked PSNR and SSIM), plus DSM MAE, held-out satellite PSNR
# and the stage times. Writes OUT/bench_idu.json, OUT/bench_idu.md and
# OUT/gallery.png (rows: 75, 60, 45 deg; columns: before, after, truth).
# On JAX_068 (no truth images) it reports held-out PSNR and DSM MAE only.
#
# Usage: scripts/bench_idu.sh [--quick] [--scene synthetic|jax068] [OUT]
#   --quick   a 128 m synthetic city instead of 256 m
# Reruns reuse finished runs (delete OUT/<scene>/rec or /idu to measure again).
# SKYFALL_BIN: the skyfall binary (default build/bin/skyfall); SKYFALL_RUN_ARGS:
# extra `skyfall run` arguments for both runs, e.g. "--set idu.samples=1".
set -euo pipefail
cd "$(dirname "$0")/.."

SIZE=256
SCENE=synthetic
OUT=out/bench_idu
while [ $# -gt 0 ]; do
  case "$1" in
    --quick) SIZE=128; shift ;;
    --scene) SCENE=$2; shift 2 ;;
    -h|--help) sed -n 2,16p "$0"; exit 0 ;;
    -*) echo "bench_idu: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) OUT=$1; shift ;;
  esac
done
source scripts/bench_env.sh
dir="$OUT/$SCENE"
mkdir -p "$dir"

case "$SCENE" in
  synthetic)
    root="$dir/input"
    SYNTH=(--size-m "$SIZE")
    [ -f "$root/synth_report.json" ] || "$B" -q synth --out "$root" "${SYNTH[@]}"
    extra=() ;;
  jax068)
    root=../shared/data/dfc2019
    [ -d "$root/Track3-Truth" ] || { echo "bench_idu: no DFC2019 data at $root" >&2; exit 1; }
    extra=(--aoi JAX_068) ;;
  *) echo "bench_idu: --scene is synthetic or jax068, not '$SCENE'" >&2; exit 2 ;;
esac

timed_run() {  # timed_run NAME IDU_MODE
  local name=$1 mode=$2
  if [ -f "$dir/$name/run_summary.json" ] && [ -f "$dir/$name.seconds" ]; then
    echo "bench_idu: reusing $dir/$name" >&2
    return
  fi
  echo "bench_idu: $name (--idu $mode) ..." >&2
  local start
  start=$(date +%s.%N)
  "$B" -q run "$root" --out "$dir/$name" --idu "$mode" "${extra[@]}" "${RUN_ARGS[@]}" 2> "$dir/$name.log"
  awk -v a="$(date +%s.%N)" -v b="$start" 'BEGIN { printf "%.1f\n", a - b }' > "$dir/$name.seconds"
}
timed_run rec off
# The IDU run starts from a copy of the reconstruction: the same SfM, dense
# heights and trained scene, so the difference is the synthesis stage alone.
if [ ! -f "$dir/idu/run_summary.json" ]; then rm -rf "$dir/idu"; cp -r "$dir/rec" "$dir/idu"; rm -f "$dir/idu.seconds"; fi
timed_run idu on

city=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['cities'][0]['city'])" "$dir/rec/run_summary.json")
tile=$(ls -d "$dir/rec/$city/tiles/"*/ | head -1)
if [ "$SCENE" = synthetic ]; then
  "$B" -q splat orbit --tile "$tile" --out "$dir/eval_cameras.json"
  for which in rec idu; do
    "$B" -q splat render --scene "$dir/$which/$city/scene/scene.ply" --cameras "$dir/eval_cameras.json" --out "$dir/render_$which"
  done
  # Truth lit as the image whose appearance the scene was fused with.
  fused=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['appearance'].get('fused_image') or '')" "$tile/splat/train_report.json")
  light=0
  if [[ "$fused" =~ _([0-9]{3})_RGB$ ]]; then light=$((10#${BASH_REMATCH[1]} - 1)); fi
  "$B" -q synth "${SYNTH[@]}" --render-cameras "$dir/eval_cameras.json" --render-out "$dir/truth" --lighting-view "$light"
  "$B" -q splat compare --cameras "$dir/eval_cameras.json" --truth "$dir/truth" --render "$dir/render_rec" \
    --render "$dir/render_idu" --out "$dir/compare"
  cp "$dir/compare/gallery.png" "$OUT/gallery.png"
fi

python3 - "$dir" "$city" "$SCENE" "$OUT" <<'PY'
import json, os, sys
d, city, scene, out = sys.argv[1:5]
def load(p):
    return json.load(open(p))
def dsm_mae(run):
    r = load(os.path.join(d, run, city, "run_report.json"))
    return (r.get("dsm") or [{}])[0].get("mae_m")
def tile_reports(run):
    base = os.path.join(d, run, city, "tiles")
    for t in sorted(os.listdir(base)):
        p = os.path.join(base, t, "tile_report.json")
        if os.path.isfile(p):
            yield load(p)
def stage_seconds(run, names):
    return sum(s["seconds"] for t in tile_reports(run) for s in t["stages"] if s["stage"] in names)
def mean(xs):
    xs = [x for x in xs if isinstance(x, (int, float))]
    return sum(xs) / len(xs) if xs else None
idu_stages = [s for t in tile_reports("idu") for s in t["stages"] if s["stage"] == "idu"]
doc = {
    "schema": "skyfall.bench_idu/1", "scene": scene,
    "dsm_mae_before_m": dsm_mae("rec"), "dsm_mae_after_m": dsm_mae("idu"),
    # Held-out satellite views rendered from the plain (appearance-fused) scene, before and after.
    "heldout_psnr_before_db": mean(s["metrics"].get("psnr_test_start_db") for s in idu_stages),
    "heldout_psnr_after_db": mean(s["metrics"].get("psnr_test_db") for s in idu_stages),
    "recon_seconds": stage_seconds("rec", {"sfm", "dense", "splat"}),
    "idu_seconds": stage_seconds("idu", {"idu"}),
    "idu_tiles": sum(1 for t in tile_reports("idu") if t.get("decisions", {}).get("idu", {}).get("on")),
    "elevations": [],
}
cmp = os.path.join(d, "compare", "compare.json")
if os.path.isfile(cmp):
    c = load(cmp)
    for e in sorted(c["per_elevation"], key=lambda e: -e["elevation_deg"]):
        doc["elevations"].append({"elevation_deg": e["elevation_deg"],
                                  "psnr_before_db": e["psnr_db"][0], "psnr_after_db": e["psnr_db"][1],
                                  "ssim_before": e["ssim"][0], "ssim_after": e["ssim"][1]})
    doc["gallery"] = os.path.join(out, "gallery.png")
tmp = os.path.join(out, "bench_idu.json.tmp")
json.dump(doc, open(tmp, "w"), indent=2)
os.replace(tmp, os.path.join(out, "bench_idu.json"))
f = lambda v, n=2: "n/a" if v is None else f"{v:.{n}f}"
lines = [f"scene: {scene}; DSM MAE {f(doc['dsm_mae_before_m'])} -> {f(doc['dsm_mae_after_m'])} m; "
         f"held-out PSNR {f(doc['heldout_psnr_before_db'])} -> {f(doc['heldout_psnr_after_db'])} dB; "
         f"reconstruction {f(doc['recon_seconds'], 0)} s, IDU {f(doc['idu_seconds'], 0)} s",
         "", "| elevation | PSNR before | PSNR after | SSIM before | SSIM after |", "|---|---|---|---|---|"]
for e in doc["elevations"]:
    lines.append(f"| {e['elevation_deg']:.0f} deg | {f(e['psnr_before_db'])} dB | {f(e['psnr_after_db'])} dB | "
                 f"{f(e['ssim_before'], 3)} | {f(e['ssim_after'], 3)} |")
open(os.path.join(out, "bench_idu.md"), "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
echo "bench_idu: $OUT/bench_idu.json, bench_idu.md, gallery.png" >&2
