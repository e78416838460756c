// The two kernels of SfM and dense heights, once per SIMD path this CPU
// runs: what scripts/bench.sh reports as dense_ms and match_ms.
// - dense_ms: the dense sweep (both passes, SGM, filling) on `--views`
//   satellite-like views (zenith 0-30 deg, every azimuth) of textured ground
//   with a 20 m plateau, drawn exactly (dense/dense_test_scene.h), every view
//   pair at a usable angle, on a grid of `--grid-m`.
// - match_ms: matching one image pair of `--descriptors` random SIFT-like
//   descriptors each (a third with a true match), both ways with the ratio
//   test, as SfM does for every pair; opencv_bf_ms: the same with OpenCV's
//   brute-force matcher (two k-nearest searches), for comparison.
//
// Usage: sfm_bench [--grid-m 192] [--views 8] [--descriptors 4000] [--repeats 2]
// Prints one JSON object on stdout.
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <random>
#include <string>

#include "core/simd.h"
#include "core/stage.h"
#include "dense/dense.h"
#include "dense/dense_test_scene.h"
#include "sfm/features.h"

namespace {

skyfall::ImageFeatures RandomDescriptors(int n, std::uint32_t seed, const skyfall::ImageFeatures* copy_from) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> value(0.0f, 100.0f), noise(-4.0f, 4.0f);
  skyfall::ImageFeatures f;
  for (int k = 0; k < n; ++k) {
    f.keypoints.emplace_back(k, k);
    const bool copy = copy_from && k % 3 == 0;
    for (int d = 0; d < 128; ++d)
      f.descriptors.push_back(copy ? copy_from->descriptors[static_cast<std::size_t>(k) * 128 + d] + noise(rng)
                                   : value(rng));
  }
  return f;
}

double OpenCvBruteForceSeconds(const skyfall::ImageFeatures& a, const skyfall::ImageFeatures& b) {
  auto mat = [](const skyfall::ImageFeatures& f) {
    return cv::Mat(static_cast<int>(f.keypoints.size()), 128, CV_32F, const_cast<float*>(f.descriptors.data()));
  };
  skyfall::Stopwatch clock;
  std::vector<std::vector<cv::DMatch>> ab, ba;
  cv::BFMatcher(cv::NORM_L2).knnMatch(mat(a), mat(b), ab, 2);
  cv::BFMatcher(cv::NORM_L2).knnMatch(mat(b), mat(a), ba, 2);
  return clock.Seconds();
}

}  // namespace

int main(int argc, char** argv) {
  using namespace skyfall;
  double grid_m = 192;
  int views_n = 8, repeats = 2, descriptors = 4000;
  for (int k = 1; k + 1 < argc; k += 2) {
    const std::string key = argv[k];
    if (key == "--grid-m") grid_m = std::atof(argv[k + 1]);
    else if (key == "--views") views_n = std::atoi(argv[k + 1]);
    else if (key == "--repeats") repeats = std::atoi(argv[k + 1]);
    else if (key == "--descriptors") descriptors = std::atoi(argv[k + 1]);
    else {
      std::cerr << "dense_bench: unknown option " << key << "\n";
      return 2;
    }
  }
  const double gsd_m = 0.5;
  const int size_px = static_cast<int>(grid_m / gsd_m * 1.25);  // margin for the oblique views' footprints
  std::vector<DenseView> views;
  for (int v = 0; v < views_n; ++v) {
    const double zenith = v == 0 ? 0.0 : 10.0 + 20.0 * (v % 3) / 2.0;
    views.push_back(testing::TexturedView("v" + std::to_string(v),
                                          testing::LookingDown(zenith, 360.0 * v / views_n, size_px, gsd_m), 20.0,
                                          grid_m / 6));
  }
  std::vector<DensePair> pairs;
  for (int a = 0; a < views_n; ++a)
    for (int b = a + 1; b < views_n; ++b) pairs.push_back({a, b, 100});
  const double h = grid_m / 2;
  const std::vector<Eigen::Vector3d> points = {{-h, -h, 0}, {h, -h, 0}, {-h, h, 0}, {h, h, 20}, {0, 0, 20}};
  NullProgress progress;
  nlohmann::json out;
  out["grid_m"] = grid_m;
  out["views"] = views_n;
  const SimdPath active = ActiveSimdPath();
  for (SimdPath path : SupportedSimdPaths()) {
    SetSimdPath(path);
    double best = 1e30;
    DenseResult r;
    for (int k = 0; k < repeats; ++k) {
      Stopwatch clock;
      r = RunDenseHeights(DenseOptions{}, views, pairs, points, progress);
      best = std::min(best, clock.Seconds());
    }
    out["dense_ms"][SimdPathName(path)] = 1e3 * best;
    out["cells"] = r.report.metrics.at("cells");
    out["heights"] = r.report.metrics.at("heights");
    out["pairs"] = r.report.metrics.at("pairs");
    out["valid_fraction"] = r.report.metrics.at("valid_fraction");
  }
  // Matching runs one pair per thread in SfM: timed on one thread here.
  const ImageFeatures a = RandomDescriptors(descriptors, 1, nullptr);
  const ImageFeatures b = RandomDescriptors(descriptors, 2, &a);
  out["descriptors"] = descriptors;
  for (SimdPath path : SupportedSimdPaths()) {
    SetSimdPath(path);
    double best = 1e30;
    for (int k = 0; k < repeats; ++k) {
      Stopwatch clock;
      out["matches"] = MatchFeatures(a, b, 0.8).size();
      best = std::min(best, clock.Seconds());
    }
    out["match_ms"][SimdPathName(path)] = 1e3 * best;
  }
  cv::setNumThreads(1);
  double best = 1e30;
  for (int k = 0; k < repeats; ++k) best = std::min(best, OpenCvBruteForceSeconds(a, b));
  out["opencv_bf_ms"] = 1e3 * best;
  SetSimdPath(active);
  out["simd"] = SimdPathName(active);
  std::cout << out.dump(1) << "\n";
  return 0;
}
