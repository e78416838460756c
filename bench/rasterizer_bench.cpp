// Forward and forward+backward of the rasterizer at 100k Gaussians, 512x384
// (the reference size). Run with scripts/bench.sh.
#include <benchmark/benchmark.h>

#include "bench/bench_scene.h"
#include "splat/appearance.h"
#include "splat/rasterizer.h"

namespace skyfall {
namespace {

void BM_Forward(benchmark::State& state) {
  const GaussianCloud cloud = BenchCloud(static_cast<int>(state.range(0)));
  const PinholeCamera cam = BenchCamera(0.0);
  const RasterOptions opts;
  double blends = 0;
  for (auto _ : state) {
    const RenderOutput<float> r = RenderGaussians(cloud, cam, opts);
    benchmark::DoNotOptimize(r.rgb.data());
    blends += static_cast<double>(r.state.blends);
  }
  state.counters["blends_per_s"] = benchmark::Counter(blends, benchmark::Counter::kIsRate);
}

void BM_ForwardBackward(benchmark::State& state) {
  const GaussianCloud cloud = BenchCloud(static_cast<int>(state.range(0)));
  const PinholeCamera cam = BenchCamera(0.0);
  const RasterOptions opts;
  const std::vector<float> d_rgb(3 * kWidth * kHeight, 1e-3f), d_alpha, d_depth;
  double blends = 0;
  for (auto _ : state) {
    const RenderOutput<float> r = RenderGaussians(cloud, cam, opts);
    const GaussianGradients<float> g = BackwardGaussians(cloud, cam, opts, r, d_rgb, d_alpha, d_depth);
    benchmark::DoNotOptimize(g.d.means.data());
    blends += 2.0 * static_cast<double>(r.state.blends);  // each blend is revisited once backwards
  }
  state.counters["blends_per_s"] = benchmark::Counter(blends, benchmark::Counter::kIsRate);
}

// The appearance MLP (59 -> 128 -> 128 -> 6) for every Gaussian, forward and
// backward: what the appearance model adds to a training iteration.
void BM_AppearanceForwardBackward(benchmark::State& state) {
  const GaussianCloud cloud = BenchCloud(static_cast<int>(state.range(0)));
  const AppearanceModel model = InitAppearance(AppearanceOptions{}, 20, cloud.size(), 3);
  const Eigen::VectorXf embedding = model.image_embeddings.col(0);
  const std::vector<ColourAffine<float>> d_affine(cloud.size(), ColourAffine<float>::Constant(1e-3f));
  for (auto _ : state) {
    AppearanceActivations<float> kept;
    const std::vector<ColourAffine<float>> affine = EvaluateAppearance(model, embedding, cloud, &kept);
    AppearanceModel grad = model.ZerosLike();
    const Eigen::VectorXf d_e = BackwardAppearance<float>(model, embedding, cloud, d_affine, &grad, nullptr, &kept);
    benchmark::DoNotOptimize(affine.data());
    benchmark::DoNotOptimize(d_e.data());
  }
}

BENCHMARK(BM_Forward)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ForwardBackward)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_AppearanceForwardBackward)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace skyfall

BENCHMARK_MAIN();
