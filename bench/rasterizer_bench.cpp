// Forward and forward+backward of the rasterizer at 100k Gaussians, 512x384
// (the reference size). Run with scripts/bench.sh.
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "splat/appearance.h"
#include "splat/rasterizer.h"

namespace skyfall {
namespace {

constexpr int kWidth = 512, kHeight = 384;

PinholeCamera BenchCamera() {
  // An oblique orbit-style camera 120 m from a 100 m scene, 60 deg FOV.
  PinholeCamera cam;
  cam.fx = cam.fy = 0.5 * kWidth / std::tan(30.0 * M_PI / 180.0);
  cam.cx = 0.5 * (kWidth - 1);
  cam.cy = 0.5 * (kHeight - 1);
  cam.width_px = kWidth;
  cam.height_px = kHeight;
  const Eigen::Vector3d centre(0, -70, 100), target(0, 0, 0);
  const Eigen::Vector3d f = (target - centre).normalized();
  const Eigen::Vector3d r = f.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d d = f.cross(r);
  cam.cam_from_world_rotation.row(0) = r.transpose();
  cam.cam_from_world_rotation.row(1) = d.transpose();
  cam.cam_from_world_rotation.row(2) = f.transpose();
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * centre;
  return cam;
}

// 100k Gaussians on a 100 m x 100 m city-like surface, ~0.3 m in size:
// what a trained tile looks like.
GaussianCloud BenchCloud(int n) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1, 1);
  GaussianCloud c;
  c.resize(n);
  for (int i = 0; i < n; ++i) {
    const float x = 50 * u(rng), y = 50 * u(rng);
    c.means[i] = Eigen::Vector3f(x, y, 10.0f * (std::sin(x * 0.2f) > 0.3f ? 1.0f : 0.0f) + 0.2f * u(rng));
    c.log_scales[i] = Eigen::Vector3f::Constant(std::log(0.3f)) + 0.3f * Eigen::Vector3f(u(rng), u(rng), u(rng));
    c.rotations[i] = Eigen::Vector4f(1, 0.3f * u(rng), 0.3f * u(rng), 0.3f * u(rng));
    c.opacity_logits[i] = 1.0f + u(rng);
    for (auto& v : c.sh[i]) v = 0.3f * u(rng);
  }
  return c;
}

void BM_Forward(benchmark::State& state) {
  const GaussianCloud cloud = BenchCloud(static_cast<int>(state.range(0)));
  const PinholeCamera cam = BenchCamera();
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
  const PinholeCamera cam = BenchCamera();
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
