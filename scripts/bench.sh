#!/usr/bin/env bash
# Speed figures (never timed unit tests). Prints, and writes to OUT/bench.json:
#   - one full training step at 100k Gaussians, 512x384, split into its phases
#     (bench/step_bench.cpp: the real TrainGaussians step with the defaults of
#     `skyfall run`), with and without the appearance model;
#   - the SIMD path the kernels run on, and the CPU (family and model);
#   - rasterizer forward and forward+backward (Google Benchmark);
#   - the dense sweep and one pair's descriptor matching per SIMD path
#     (bench/sfm_bench.cpp), with OpenCV's brute-force matcher for comparison;
#   - synthetic scene generation and ingestion;
#   - JAX_068 end to end (`skyfall run` defaults) with its stage times, when
#     ../shared/data/dfc2019 is there (about 10 minutes; --no-jax skips it).
# Usage: scripts/bench.sh [--no-jax] [OUT]   (OUT defaults to out/bench)
set -euo pipefail
cd "$(dirname "$0")/.."
JAX_RUN=1
if [ "${1:-}" = "--no-jax" ]; then JAX_RUN=0; shift; fi
case "${1:-}" in -*) echo "bench: unknown option $1 (usage: scripts/bench.sh [--no-jax] [OUT])" >&2; exit 2 ;; esac
OUT=${1:-out/bench}
mkdir -p "$OUT"
bash scripts/build.sh >/dev/null
B=./build/bin/skyfall
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
elapsed() { awk -v a="$1" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.2f", b - a }'; }

# 1. One training step, both appearance models and none (40 steps each; the
# mean per step is reported). bench.json's step_ms is the step with the
# appearance model `skyfall run` uses by default on multi-date imagery.
default_model=$($B run --print-config | python3 -c 'import json, sys; print(json.load(sys.stdin)["train"]["appearance_model"]["model"])')
for model in off bilinear mlp; do
  ./build/bin/step_bench --steps 40 --appearance "$model" > "$tmp/step_$model.json"
done
# The same step on the baseline SIMD path, for the gain of the wider ones.
SKYFALL_SIMD=baseline ./build/bin/step_bench --steps 40 --appearance "$default_model" > "$tmp/step_baseline.json"
python3 - "$tmp" <<'PY'
import json, sys
for model in ("off", "bilinear", "mlp"):
    s = json.load(open(f"{sys.argv[1]}/step_{model}.json"))
    parts = ", ".join(f"{k[:-3]} {v:.1f}" for k, v in s.items() if k.endswith("_ms") and k != "step_ms" and v >= 0.05)
    print(f"training step, {s['gaussians']} Gaussians {s['width_px']}x{s['height_px']}, appearance {model}: "
          f"{s['step_ms']:.1f} ms ({parts})")
b = json.load(open(f"{sys.argv[1]}/step_baseline.json"))
print(f"the same step (default appearance model) on the baseline SIMD path: {b['step_ms']:.1f} ms "
      f"(raster_fwd {b['raster_fwd_ms']:.1f}, raster_bwd {b['raster_bwd_ms']:.1f})")
PY

# 2. Rasterizer alone, and the SIMD path.
./build/bin/rasterizer_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true \
  --benchmark_format=json --benchmark_out="$tmp/raster.json" --benchmark_out_format=json >/dev/null 2>&1
simd=$($B --version | sed -n 's/^SIMD path: //p')
echo "SIMD path: $simd"
# The CPU the figures were taken on. The same code's step time differs by
# about 1.4x between the 2-core machines this project runs on (AMD EPYC of
# family 25 and 26), so figures compare only on the same family and model.
cpu=$(python3 - <<'PY'
import json, os
info = {}
try:
    for line in open("/proc/cpuinfo"):
        key, _, value = line.partition(":")
        key, value = key.strip(), value.strip()
        if key in ("model name", "cpu family", "model", "stepping") and key not in info:
            info[key] = value
except OSError:
    pass
print(json.dumps({"model_name": info.get("model name"), "family": info.get("cpu family"),
                  "model": info.get("model"), "stepping": info.get("stepping"), "cores": os.cpu_count()}))
PY
)
echo "CPU: $cpu"

# 2b. SfM's matching and the dense sweep, per SIMD path.
./build/bin/sfm_bench --grid-m 192 --views 8 --descriptors 4000 --repeats 2 > "$tmp/sfm.json"
python3 - "$tmp/sfm.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
print(f"dense sweep, {int(s['cells'])} cells x {int(s['heights'])} heights, {int(s['pairs'])} pairs: " +
      ", ".join(f"{k} {v:.0f} ms" for k, v in s["dense_ms"].items()))
print(f"matching one pair of {s['descriptors']} descriptors: " +
      ", ".join(f"{k} {v:.0f} ms" for k, v in s["match_ms"].items()) + f"; OpenCV brute force {s['opencv_bf_ms']:.0f} ms")
PY

# 3. Synthetic scene and ingestion.
start=$EPOCHREALTIME
$B -q synth --out "$tmp/synth" >/dev/null
synth_s=$(elapsed "$start")
start=$EPOCHREALTIME
$B -q ingest "$tmp/synth" --out "$tmp/catalogs" >/dev/null
ingest_s=$(elapsed "$start")
echo "synth default scene (256 m, 12 views): $synth_s s; its ingestion: $ingest_s s"

# 4. JAX_068 end to end.
JAX=../shared/data/dfc2019
jax_dir=""
if [ "$JAX_RUN" = 1 ] && [ -d "$JAX/Track3-Truth" ]; then
  jax_dir="$OUT/jax068"
  rm -rf "$jax_dir"
  start=$EPOCHREALTIME
  $B -q run "$JAX" --out "$jax_dir" --aoi JAX_068 2> "$OUT/jax068.log" || echo "bench: the JAX_068 run failed, see $OUT/jax068.log" >&2
  elapsed "$start" > "$OUT/jax068_wall_seconds"
fi

python3 - "$tmp" "$OUT" "$simd" "$synth_s" "$ingest_s" "$jax_dir" "$default_model" "$cpu" <<'PY'
import glob, json, os, sys
tmp, out, simd, synth_s, ingest_s, jax_dir, default_model, cpu = sys.argv[1:9]
steps = {m: json.load(open(f"{tmp}/step_{m}.json")) for m in ("off", "bilinear", "mlp")}
raster = {}
for b in json.load(open(f"{tmp}/raster.json"))["benchmarks"]:
    if b.get("aggregate_name") == "median":
        raster[b["run_name"].split("/")[0]] = b["real_time"]
default = steps[default_model]
doc = {
    "schema": "skyfall.bench/1",
    "simd": simd.split()[0] if simd else None,
    "simd_detail": simd,
    "cpu": json.loads(cpu),
    "baseline_simd_step": json.load(open(f"{tmp}/step_baseline.json")),
    "step_ms": default["step_ms"],
    "raster_fwd_ms": default["raster_fwd_ms"],
    "raster_bwd_ms": default["raster_bwd_ms"],
    "appearance_ms": default["appearance_ms"],
    "loss_ms": default["loss_ms"],
    "optimizer_ms": default["optimizer_ms"],
    "step_appearance_model": default_model,
    "steps_by_appearance_model": steps,
    "rasterizer_bench_median_ms": raster,
    "sfm_kernels": json.load(open(f"{tmp}/sfm.json")),
    "dense_ms": json.load(open(f"{tmp}/sfm.json"))["dense_ms"].get(simd.split()[0] if simd else "baseline"),
    "match_ms": json.load(open(f"{tmp}/sfm.json"))["match_ms"].get(simd.split()[0] if simd else "baseline"),
    "synth_default_s": float(synth_s),
    "ingest_default_s": float(ingest_s),
}
print("rasterizer alone (median of 3): " + ", ".join(f"{k} {v:.1f} ms" for k, v in raster.items()))
if jax_dir:
    wall = float(open(os.path.join(out, "jax068_wall_seconds")).read())
    jax = {"wall_s": wall}
    reports = glob.glob(os.path.join(jax_dir, "*", "run_report.json"))
    if reports:
        r = json.load(open(reports[0]))
        jax["city_stages_s"] = {s["stage"]: s["seconds"] for s in r.get("stages", [])}
        tile_stages = {}
        for t in r.get("tiles", []):
            for s in t.get("stages", []):
                if isinstance(s.get("seconds"), (int, float)):
                    tile_stages[s["stage"]] = tile_stages.get(s["stage"], 0) + s["seconds"]
        jax["tile_stages_s"] = tile_stages
        dsm = (r.get("dsm") or [{}])[0]
        jax["dsm_mae_m"] = dsm.get("mae_m")
        jax["peak_tile_rss_mb"] = r.get("peak_tile_rss_mb")
        psnrs = [s["metrics"]["psnr_test_db"] for t in r.get("tiles", []) for s in t.get("stages", [])
                 if s.get("stage") == "splat" and isinstance(s.get("metrics", {}).get("psnr_test_db"), (int, float))]
        jax["heldout_psnr_db"] = sum(psnrs) / len(psnrs) if psnrs else None
    doc["jax068"] = jax
    print(f"JAX_068 end to end: {wall:.0f} s; stages: " +
          ", ".join(f"{k} {v:.0f} s" for k, v in {**jax.get("city_stages_s", {}), **jax.get("tile_stages_s", {})}.items()) +
          f"; DSM MAE {jax.get('dsm_mae_m')} m, held-out PSNR {jax.get('heldout_psnr_db')} dB, "
          f"peak tile memory {jax.get('peak_tile_rss_mb')} MB")
with open(os.path.join(out, "bench.json.tmp"), "w") as f:
    json.dump(doc, f, indent=2)
os.replace(os.path.join(out, "bench.json.tmp"), os.path.join(out, "bench.json"))
print(f"bench: {out}/bench.json")
PY
