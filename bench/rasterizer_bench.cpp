// Forward and forward+backward of the rasterizer at 100k Gaussians, 512x384
// (the reference size). Run with scripts/bench.sh.
#include <benchmark/benchmark.h>

#include "bench/bench_scene.h"
#include "core/allocator.h"
#include "splat/appearance.h"
#include "splat/depth_prior.h"
#include "splat/losses.h"
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

// Forward and backward of the surface anchor's nadir patch (192 px at
// 0.5 m, the training defaults), placed over a corner of the 100 m scene so
// that it sees about a tenth of the cloud (11.3k of 100k Gaussians; the
// patches of step_bench saw 10.9k): what it costs beyond its blending is the
// per-Gaussian pass.
void BM_NadirPatchForwardBackward(benchmark::State& state) {
  const GaussianCloud cloud = BenchCloud(static_cast<int>(state.range(0)));
  const PinholeCamera cam = NadirCamera(Eigen::Vector3d(65, -65, 0), 0.5, 192, 1.0e5);
  const RasterOptions opts;
  const std::vector<float> d_rgb, d_alpha(192 * 192, 1e-3f), d_depth(192 * 192, 1e-3f);
  for (auto _ : state) {
    const RenderOutput<float> r = RenderGaussians(cloud, cam, opts);
    const GaussianGradients<float> g = BackwardGaussians(cloud, cam, opts, r, d_rgb, d_alpha, d_depth);
    benchmark::DoNotOptimize(g.d.means.data());
  }
}

// The appearance MLP (59 -> 32 -> 32 -> 6, the default width) for every Gaussian, forward and
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

// The photometric loss (L1 + D-SSIM) with its gradient on one RGB image of
// width x height: the training step's loss phase.
void BM_PhotometricLoss(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  std::vector<float> x(3 * static_cast<std::size_t>(w) * h), target(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) {
    x[k] = 0.5f + 0.4f * std::sin(0.37f * static_cast<float>(k));
    target[k] = 0.5f + 0.4f * std::cos(0.11f * static_cast<float>(k));
  }
  std::vector<float> grad;
  for (auto _ : state) {
    benchmark::DoNotOptimize(PhotometricLoss(x, target, w, h, PhotometricLossOptions{}, &grad));
    benchmark::DoNotOptimize(grad.data());
  }
}

BENCHMARK(BM_Forward)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ForwardBackward)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_NadirPatchForwardBackward)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_AppearanceForwardBackward)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_PhotometricLoss)->Args({256, 256})->Args({512, 384})->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace skyfall

int main(int argc, char** argv) {
  skyfall::KeepFreedMemoryForReuse();  // as the skyfall binary does
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
