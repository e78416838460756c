#include "splat/raster_test_support.h"
#include "splat/rasterizer.h"

#include "core/error.h"
#include "core/simd.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <iostream>
#include <random>

namespace skyfall {
namespace {

using Cloud = GaussianCloudT<double>;

using testing::SmoothRasterOptions;

// A camera looking down -z from `height_m` above the origin, like an orbit
// or pseudo camera (FOV from the focal length and size).
PinholeCamera LookDownCamera(double focal_px, int w, int h, double height_m, double skew = 0.0) {
  PinholeCamera cam;
  cam.fx = focal_px;
  cam.fy = focal_px * 1.01;
  cam.skew = skew;
  cam.cx = 0.5 * (w - 1) + 1.3;
  cam.cy = 0.5 * (h - 1) - 0.7;
  cam.width_px = w;
  cam.height_px = h;
  // Tilted a little so no axis is special; rows: right, down, forward.
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()) *
                                Eigen::AngleAxisd(-0.1, Eigen::Vector3d::UnitY()))
                                   .toRotationMatrix();
  Eigen::Matrix3d down;
  down << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // camera x = east, y = south, z = down
  cam.cam_from_world_rotation = tilt * down;
  // Aimed at a point near the origin from `height_m` along the optical axis.
  const Eigen::Vector3d forward = cam.cam_from_world_rotation.row(2).transpose();
  const Eigen::Vector3d centre = Eigen::Vector3d(0.3, -0.2, 0.0) - height_m * forward;
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * centre;
  return cam;
}

Cloud RandomCloud(int n, double spread_m, double scale_m, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  Cloud c;
  c.resize(n);
  for (int i = 0; i < n; ++i) {
    c.means[i] = Eigen::Vector3d(spread_m * u(rng), spread_m * u(rng), 0.3 * spread_m * u(rng));
    c.log_scales[i] = Eigen::Vector3d::Constant(std::log(scale_m)) + 0.3 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    c.rotations[i] = Eigen::Vector4d(1 + 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng));
    c.opacity_logits[i] = 0.8 * u(rng);
    for (auto& v : c.sh[i]) v = 0.4 * u(rng);
    c.sh[i][0] += 0.5;
    c.sh[i][4] -= 0.3;
  }
  return c;
}

struct Weights {
  std::vector<double> rgb, alpha, depth;
};

Weights RandomWeights(const PinholeCamera& cam, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const std::size_t n = static_cast<std::size_t>(cam.width_px) * cam.height_px;
  Weights w;
  for (std::size_t k = 0; k < 3 * n; ++k) w.rgb.push_back(u(rng));
  for (std::size_t k = 0; k < n; ++k) w.alpha.push_back(u(rng));
  for (std::size_t k = 0; k < n; ++k) w.depth.push_back(0.1 * u(rng));
  return w;
}

// L = sum of weighted RGB, alpha and expected depth.
double Loss(const Cloud& c, const PinholeCamera& cam, const RasterOptions& o, const Weights& w) {
  const RenderOutput<double> r = RenderGaussians(c, cam, o);
  double l = 0;
  for (std::size_t k = 0; k < r.rgb.size(); ++k) l += w.rgb[k] * r.rgb[k];
  for (std::size_t k = 0; k < r.alpha.size(); ++k) l += w.alpha[k] * r.alpha[k] + w.depth[k] * r.depth[k];
  return l;
}

// Compares every analytic gradient with a central difference.
void CheckGradients(const Cloud& cloud, const PinholeCamera& cam, const RasterOptions& o, double step_mean,
                    double rel_tol, double abs_tol) {
  const Weights w = RandomWeights(cam, 11);
  const RenderOutput<double> fwd = RenderGaussians(cloud, cam, o);
  // Every Gaussian must be on screen, or the check proves nothing.
  for (std::size_t i = 0; i < cloud.size(); ++i) ASSERT_GT(fwd.state.radius_px[i], 0) << "Gaussian " << i;
  double coverage = 0;
  for (double a : fwd.alpha) coverage += a;
  ASSERT_GT(coverage / fwd.alpha.size(), 0.15) << "the image is mostly empty";
  const GaussianGradients<double> g = BackwardGaussians(cloud, cam, o, fwd, w.rgb, w.alpha, w.depth);
  int checked = 0;
  auto check = [&](double* param, double analytic, double step, const char* what, int i) {
    const double keep = *param;
    Cloud& c = const_cast<Cloud&>(cloud);
    *param = keep + step;
    const double lp = Loss(c, cam, o, w);
    *param = keep - step;
    const double lm = Loss(c, cam, o, w);
    *param = keep;
    const double fd = (lp - lm) / (2 * step);
    EXPECT_NEAR(analytic, fd, abs_tol + rel_tol * std::abs(fd)) << what << " of Gaussian " << i;
    ++checked;
  };
  Cloud& c = const_cast<Cloud&>(cloud);
  for (int i = 0; i < static_cast<int>(c.size()); ++i) {
    for (int k = 0; k < 3; ++k) check(&c.means[i][k], g.d.means[i][k], step_mean, "mean", i);
    for (int k = 0; k < 3; ++k) check(&c.log_scales[i][k], g.d.log_scales[i][k], 1e-6, "log_scale", i);
    for (int k = 0; k < 4; ++k) check(&c.rotations[i][k], g.d.rotations[i][k], 1e-6, "rotation", i);
    check(&c.opacity_logits[i], g.d.opacity_logits[i], 1e-6, "opacity", i);
    for (int k = 0; k < 12; ++k) check(&c.sh[i][k], g.d.sh[i][k], 1e-6, "sh", i);
  }
  EXPECT_EQ(checked, static_cast<int>(c.size()) * 23);
}

TEST(Rasterizer, GradientsMatchFiniteDifferencesForANearCamera) {
  // 60-degree field of view, 40 m up: an orbit / pseudo camera.
  const PinholeCamera cam = LookDownCamera(41.6, 48, 40, 20.0, 0.8);
  const Cloud cloud = RandomCloud(6, 7.0, 3.0, 1);
  CheckGradients(cloud, cam, SmoothRasterOptions(), 1e-6, 2e-5, 1e-7);
}

TEST(Rasterizer, GradientsMatchFiniteDifferencesForASatelliteCamera) {
  // WorldView-3-like: f = 2e6 px, 6e5 m away, 0.3 m pixels, with skew.
  const PinholeCamera cam = LookDownCamera(2.0e6, 40, 36, 6.0e5, 3.0e4);
  const Cloud cloud = RandomCloud(5, 3.0, 1.5, 2);
  // The mean step must move the 6e5 m camera-frame depth by representable
  // amounts: 1e-5 m leaves ~1e-11 relative, ample in double.
  CheckGradients(cloud, cam, SmoothRasterOptions(), 1e-5, 1e-4, 1e-7);
}

TEST(Rasterizer, GradientsAtExtremes) {
  const PinholeCamera cam = LookDownCamera(41.6, 40, 32, 20.0);
  Cloud cloud = RandomCloud(6, 6.0, 2.5, 3);
  cloud.log_scales[0] = Eigen::Vector3d(std::log(3.0), std::log(2e-3), std::log(2.0));  // a thin sheet
  cloud.log_scales[1] = Eigen::Vector3d::Constant(std::log(40.0));                     // covers the image
  cloud.opacity_logits[2] = -9.0;                                                       // opacity ~1e-4
  cloud.opacity_logits[3] = 4.0;                                                        // opacity 0.982
  // Centre just outside the left image border, footprint inside.
  const Eigen::Vector3d forward = cam.cam_from_world_rotation.row(2).transpose();
  const Eigen::Vector3d right = cam.cam_from_world_rotation.row(0).transpose();
  cloud.means[4] = cam.Centre() + 20.0 * forward - 10.5 * right;
  ASSERT_LT(cam.Project(cloud.means[4]).x(), 0.0);
  CheckGradients(cloud, cam, SmoothRasterOptions(), 1e-6, 5e-5, 1e-7);
}

TEST(Rasterizer, GaussiansBehindTheCameraAreCulledWithZeroGradient) {
  const PinholeCamera cam = LookDownCamera(41.6, 32, 32, 40.0);
  Cloud cloud = RandomCloud(3, 5.0, 1.0, 4);
  const Eigen::Vector3d forward = cam.cam_from_world_rotation.row(2).transpose();
  cloud.means[1] = cam.Centre() - 5.0 * forward;  // behind the camera
  cloud.means[2] = cam.Centre() + 0.1 * forward;  // closer than the near plane
  const Weights w = RandomWeights(cam, 5);
  const RenderOutput<double> r = RenderGaussians(cloud, cam, SmoothRasterOptions());
  const GaussianGradients<double> g = BackwardGaussians(cloud, cam, SmoothRasterOptions(), r, w.rgb, w.alpha, w.depth);
  for (int i : {1, 2}) {
    EXPECT_EQ(r.state.radius_px[i], 0);
    EXPECT_EQ(g.d.means[i].norm(), 0.0);
    EXPECT_EQ(g.d.opacity_logits[i], 0.0);
  }
  for (double v : r.rgb) EXPECT_TRUE(std::isfinite(v));
  EXPECT_GT(g.d.means[0].norm(), 0.0);
}

// A big Gaussian just past the near plane, far to the side, projects
// beyond the guard band with a footprint larger than the image: culled, so
// it does not veil the view; the same Gaussian inside the band still blends.
TEST(Rasterizer, GaussiansFarOutsideTheImageNearTheCameraPlaneAreCulled) {
  const PinholeCamera cam = LookDownCamera(41.6, 32, 32, 40.0);
  const Eigen::Vector3d forward = cam.cam_from_world_rotation.row(2).transpose();
  const Eigen::Vector3d right = cam.cam_from_world_rotation.row(0).transpose();
  Cloud cloud = RandomCloud(1, 5.0, 1.0, 4);
  cloud.log_scales[0] = Eigen::Vector3d::Constant(std::log(2.0));
  cloud.opacity_logits[0] = 4.0;
  RasterOptions o;
  // 1 m in front of the camera plane, 5 m to the side: u = 16 + 41.6 * 5 = 224 px, far beyond 32 x 1.3.
  cloud.means[0] = cam.Centre() + 1.0 * forward + 5.0 * right;
  const RenderOutput<double> outside = RenderGaussians(cloud, cam, o);
  EXPECT_EQ(outside.state.radius_px[0], 0);
  for (double a : outside.alpha) EXPECT_EQ(a, 0.0);
  o.guard_band = 10.0;  // a band that reaches it: it now covers the image
  const RenderOutput<double> veiled = RenderGaussians(cloud, cam, o);
  EXPECT_GT(veiled.alpha[16 * 32 + 16], 0.5);
  o.guard_band = -1.0;
  EXPECT_THROW(o.Check(), Error);
}

TEST(Rasterizer, FootprintIsTheSigmaEllipseAtEveryTileAndImageEdge) {
  // A long, rotated, opaque Gaussian crossing tile borders and the image
  // border, in an image whose width is not a multiple of the tile or the
  // vector width: exactly the pixels within sigma_extent (Mahalanobis) are
  // blended, whatever lane or tile they fall in.
  const PinholeCamera cam = LookDownCamera(41.6, 37, 29, 20.0);
  Cloud c = RandomCloud(1, 0.0, 1.0, 9);
  c.means[0] = Eigen::Vector3d(2.0, -1.0, 0.0);
  c.log_scales[0] = Eigen::Vector3d(std::log(9.0), std::log(2.0), std::log(0.5));
  c.rotations[0] = Eigen::Vector4d(std::cos(0.3), 0.0, 0.0, std::sin(0.3));
  c.opacity_logits[0] = 5.0;
  RasterOptions o;
  o.min_alpha = 0.0;
  o.sigma_extent = 3.0;
  const RenderOutput<double> r = RenderGaussians(c, cam, o);
  const ScreenGaussian<double>& q = r.state.screen[0];
  int inside = 0, outside = 0;
  for (int y = 0; y < cam.height_px; ++y) {
    for (int x = 0; x < cam.width_px; ++x) {
      const double dx = q.u - x, dy = q.v - y;
      const double mahalanobis2 = q.conic_a * dx * dx + 2 * q.conic_b * dx * dy + q.conic_c * dy * dy;
      const double a = r.alpha[static_cast<std::size_t>(y) * cam.width_px + x];
      // Pixels within 1e-9 of the boundary may go either way.
      if (std::abs(mahalanobis2 - 9.0) < 1e-9) continue;
      if (mahalanobis2 < 9.0) {
        EXPECT_GT(a, 0.0) << x << "," << y;
        ++inside;
      } else {
        EXPECT_EQ(a, 0.0) << x << "," << y;
        ++outside;
      }
    }
  }
  EXPECT_GT(inside, 100);
  EXPECT_GT(outside, 100);
}

TEST(Rasterizer, FloatKernelMatchesTheDoubleOne) {
  // Training runs the float kernel (a polynomial exp, float sums); the
  // finite-difference tests check the double one. Same inputs, same
  // results to float precision: colours and alpha within 2e-5 (~100 float
  // ulps), every gradient within 1e-3 of its magnitude (float sums over
  // ~1e3 pixels).
  const PinholeCamera cam = LookDownCamera(41.6, 45, 38, 20.0, 0.5);
  const Cloud cd = RandomCloud(30, 8.0, 1.5, 21);
  const GaussianCloudT<float> cf = testing::ToFloat(cd);
  const RasterOptions o = SmoothRasterOptions();
  const Weights w = RandomWeights(cam, 3);
  const std::vector<float> wf_rgb(w.rgb.begin(), w.rgb.end()), wf_alpha(w.alpha.begin(), w.alpha.end()),
      wf_depth(w.depth.begin(), w.depth.end());
  const RenderOutput<double> rd = RenderGaussians(cd, cam, o);
  const RenderOutput<float> rf = RenderGaussians(cf, cam, o);
  for (std::size_t k = 0; k < rd.rgb.size(); ++k) ASSERT_NEAR(rf.rgb[k], rd.rgb[k], 2e-5) << k;
  for (std::size_t k = 0; k < rd.alpha.size(); ++k) ASSERT_NEAR(rf.alpha[k], rd.alpha[k], 2e-5) << k;
  // Depth as accumulated (expected depth x alpha): the division by a tiny
  // alpha at a footprint's rim amplifies float rounding, not kernel errors.
  // Depths are ~10 m: 1e-4 m is ~100 float ulps.
  for (std::size_t k = 0; k < rd.depth.size(); ++k) {
    ASSERT_NEAR(rf.depth[k] * rf.alpha[k], rd.depth[k] * rd.alpha[k], 1e-4) << k;
  }
  const GaussianGradients<double> gd = BackwardGaussians(cd, cam, o, rd, w.rgb, w.alpha, w.depth);
  const GaussianGradients<float> gf = BackwardGaussians(cf, cam, o, rf, wf_rgb, wf_alpha, wf_depth);
  auto near = [](double f, double d, double scale, const char* what, std::size_t i) {
    EXPECT_NEAR(f, d, 1e-3 * scale) << what << " of Gaussian " << i;
  };
  for (std::size_t i = 0; i < cd.size(); ++i) {
    const double sm = gd.d.means[i].norm() + 1e-3, ss = gd.d.log_scales[i].norm() + 1e-3;
    const double sr = gd.d.rotations[i].norm() + 1e-3, sh = Eigen::Map<const Eigen::VectorXd>(gd.d.sh[i].data(), 12).norm() + 1e-3;
    for (int k = 0; k < 3; ++k) near(gf.d.means[i][k], gd.d.means[i][k], sm, "mean", i);
    for (int k = 0; k < 3; ++k) near(gf.d.log_scales[i][k], gd.d.log_scales[i][k], ss, "log_scale", i);
    for (int k = 0; k < 4; ++k) near(gf.d.rotations[i][k], gd.d.rotations[i][k], sr, "rotation", i);
    near(gf.d.opacity_logits[i], gd.d.opacity_logits[i], std::abs(gd.d.opacity_logits[i]) + 1e-3, "opacity", i);
    for (int k = 0; k < 12; ++k) near(gf.d.sh[i][k], gd.d.sh[i][k], sh, "sh", i);
  }
}

using testing::ScopedSimdPath;

TEST(Rasterizer, EverySimdPathGivesTheBaselineResults) {
  // Per pixel the paths run the same arithmetic in wider vectors (the AVX2
  // and AVX-512 ones with fused multiply-adds where GCC contracts), so
  // images agree within a few float roundings: 1e-6.
  // Gradients are float sums over pixels in lane-width order: within 3e-5 of
  // each Gaussian's largest gradient entry (AVX2 against the baseline
  // measured 4e-6). Default options here: alpha cut and early stop on, which
  // the finite-difference tests switch off.
  constexpr double kImageTol = 1e-6, kGradientTol = 3e-5;
  const PinholeCamera cam = LookDownCamera(60.0, 97, 70, 20.0, 0.5);
  const GaussianCloudT<float> cloud = testing::ToFloat(RandomCloud(400, 9.0, 0.4, 5));
  RasterOptions o;
  o.median_depth = true;
  const Weights w = RandomWeights(cam, 4);
  const std::vector<float> wf_rgb(w.rgb.begin(), w.rgb.end()), wf_alpha(w.alpha.begin(), w.alpha.end()),
      wf_depth(w.depth.begin(), w.depth.end());
  RenderOutput<float> base;
  GaussianGradients<float> base_g;
  {
    ScopedSimdPath scoped(SimdPath::kBaseline);
    base = RenderGaussians(cloud, cam, o);
    base_g = BackwardGaussians(cloud, cam, o, base, wf_rgb, wf_alpha, wf_depth);
  }
  ASSERT_GT(base.state.blends, 10000u) << "too little blending to compare";
  for (SimdPath path : SupportedSimdPaths()) {
    SCOPED_TRACE(SimdPathName(path));
    ScopedSimdPath scoped(path);
    const RenderOutput<float> r = RenderGaussians(cloud, cam, o);
    EXPECT_EQ(r.state.blends, base.state.blends);
    for (std::size_t k = 0; k < r.rgb.size(); ++k) ASSERT_NEAR(r.rgb[k], base.rgb[k], kImageTol) << k;
    for (std::size_t k = 0; k < r.alpha.size(); ++k) {
      ASSERT_NEAR(r.alpha[k], base.alpha[k], kImageTol) << k;
      ASSERT_NEAR(r.depth[k] * r.alpha[k], base.depth[k] * base.alpha[k], 10 * kImageTol) << k;  // depths ~10 m
      if (std::isnan(base.median_depth[k])) {
        ASSERT_TRUE(std::isnan(r.median_depth[k])) << k;
      } else {
        ASSERT_EQ(r.median_depth[k], base.median_depth[k]) << k;
      }
    }
    // Each Gaussian's gradient against its own largest entry: single
    // entries (the opacity's, most often) can be sums that cancel to ~1e-3
    // of their terms, where float rounding in another order shows.
    const GaussianGradients<float> g = BackwardGaussians(cloud, cam, o, r, wf_rgb, wf_alpha, wf_depth);
    double worst = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      double diff = 0, norm = 0;
      auto add = [&](const float* a, const float* b, int n) {
        for (int k = 0; k < n; ++k) {
          diff = std::max(diff, static_cast<double>(std::abs(a[k] - b[k])));
          norm = std::max(norm, static_cast<double>(std::abs(b[k])));
        }
      };
      add(g.d.means[i].data(), base_g.d.means[i].data(), 3);
      add(g.d.log_scales[i].data(), base_g.d.log_scales[i].data(), 3);
      add(g.d.rotations[i].data(), base_g.d.rotations[i].data(), 4);
      add(&g.d.opacity_logits[i], &base_g.d.opacity_logits[i], 1);
      add(g.d.sh[i].data(), base_g.d.sh[i].data(), 12);
      if (norm > 0) worst = std::max(worst, diff / norm);
    }
    EXPECT_LT(worst, kGradientTol);
    std::cout << SimdPathName(path) << ": largest gradient difference " << worst << " of its block\n";
  }
  if (SupportedSimdPaths().size() < 3) {
    std::cout << "note: this CPU runs " << SupportedSimdPaths().size() << " of the 3 SIMD paths; the others are untested here\n";
  }
}

TEST(Rasterizer, TilesThatAreNotWholePixelBlocksGiveTheSameRender) {
  // The blending loops work on blocks of 1 x 4, 2 x 4 or 4 x 4 pixels per
  // vector (4, 8, 16 lanes) and pad a tile to whole blocks. A tile side
  // that is no multiple of the block (5, 7, 13 px) leaves padding lanes at
  // every tile's right and bottom edge, which must blend nothing. Per pixel
  // the arithmetic is the same whatever the tile size, so images agree to a
  // float rounding (1e-6); gradients are sums over differently cut tiles
  // (kGradientTol of the SIMD test above).
  constexpr double kImageTol = 1e-6, kGradientTol = 3e-5;
  const PinholeCamera cam = LookDownCamera(60.0, 97, 70, 20.0, 0.5);
  const GaussianCloudT<float> cloud = testing::ToFloat(RandomCloud(400, 9.0, 0.4, 5));
  const Weights w = RandomWeights(cam, 4);
  const std::vector<float> wf_rgb(w.rgb.begin(), w.rgb.end()), wf_alpha(w.alpha.begin(), w.alpha.end()),
      wf_depth(w.depth.begin(), w.depth.end());
  for (SimdPath path : SupportedSimdPaths()) {
    ScopedSimdPath scoped(path);
    RasterOptions o;
    o.median_depth = true;
    const RenderOutput<float> ref = RenderGaussians(cloud, cam, o);
    const GaussianGradients<float> ref_g = BackwardGaussians(cloud, cam, o, ref, wf_rgb, wf_alpha, wf_depth);
    ASSERT_GT(ref.state.blends, 10000u) << "too little blending to compare";
    for (int tile_px : {5, 7, 13}) {
      SCOPED_TRACE(std::string(SimdPathName(path)) + ", tile " + std::to_string(tile_px) + " px");
      o.tile_px = tile_px;
      const RenderOutput<float> r = RenderGaussians(cloud, cam, o);
      EXPECT_EQ(r.state.blends, ref.state.blends);
      for (std::size_t k = 0; k < r.rgb.size(); ++k) ASSERT_NEAR(r.rgb[k], ref.rgb[k], kImageTol) << k;
      for (std::size_t k = 0; k < r.alpha.size(); ++k) {
        ASSERT_NEAR(r.alpha[k], ref.alpha[k], kImageTol) << k;
        ASSERT_EQ(std::isnan(r.median_depth[k]), std::isnan(ref.median_depth[k])) << k;
        if (!std::isnan(ref.median_depth[k])) {
          ASSERT_EQ(r.median_depth[k], ref.median_depth[k]) << k;
        }
      }
      const GaussianGradients<float> g = BackwardGaussians(cloud, cam, o, r, wf_rgb, wf_alpha, wf_depth);
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        const float scale = ref_g.d.means[i].cwiseAbs().maxCoeff() + ref_g.d.log_scales[i].cwiseAbs().maxCoeff() +
                            std::abs(ref_g.d.opacity_logits[i]);
        ASSERT_LE((g.d.means[i] - ref_g.d.means[i]).cwiseAbs().maxCoeff(), kGradientTol * scale + 1e-12) << i;
        ASSERT_LE((g.d.log_scales[i] - ref_g.d.log_scales[i]).cwiseAbs().maxCoeff(), kGradientTol * scale + 1e-12) << i;
        ASSERT_LE(std::abs(g.d.opacity_logits[i] - ref_g.d.opacity_logits[i]), kGradientTol * scale + 1e-12) << i;
      }
    }
  }
}

TEST(Rasterizer, WithoutAColourGradientTheGeometryGradientsAreTheSame) {
  // No colour gradient (an empty d_rgb, as the regularizer views pass)
  // takes a blending loop without the colour terms. They would all be zero,
  // so every geometry and opacity gradient must be bit-identical to the
  // full loop's with a zero colour gradient, and the colour gradients zero.
  const PinholeCamera cam = LookDownCamera(60.0, 97, 70, 20.0, 0.5);
  const GaussianCloudT<float> cloud = testing::ToFloat(RandomCloud(400, 9.0, 0.4, 5));
  const Weights w = RandomWeights(cam, 4);
  const std::vector<float> wf_alpha(w.alpha.begin(), w.alpha.end()), wf_depth(w.depth.begin(), w.depth.end());
  const std::vector<float> zero_rgb(w.rgb.size(), 0.0f);
  for (SimdPath path : SupportedSimdPaths()) {
    SCOPED_TRACE(SimdPathName(path));
    ScopedSimdPath scoped(path);
    const RasterOptions o;
    const RenderOutput<float> r = RenderGaussians(cloud, cam, o);
    ASSERT_GT(r.state.blends, 10000u);
    const GaussianGradients<float> full = BackwardGaussians(cloud, cam, o, r, zero_rgb, wf_alpha, wf_depth);
    const GaussianGradients<float> geometry = BackwardGaussians(cloud, cam, o, r, {}, wf_alpha, wf_depth);
    int moved = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      ASSERT_EQ(geometry.d.means[i], full.d.means[i]) << i;
      ASSERT_EQ(geometry.d.log_scales[i], full.d.log_scales[i]) << i;
      ASSERT_EQ(geometry.d.rotations[i], full.d.rotations[i]) << i;
      ASSERT_EQ(geometry.d.opacity_logits[i], full.d.opacity_logits[i]) << i;
      for (float v : geometry.d.sh[i]) {
        ASSERT_EQ(v, 0.0f) << i;
      }
      moved += geometry.d.means[i].norm() > 0;
    }
    EXPECT_GT(moved, 100) << "the depth and alpha weights must move most Gaussians";
  }
}

TEST(Simd, PathsParseAndUnsupportedOnesAreRefused) {
  EXPECT_EQ(ParseSimdPath("avx2"), SimdPath::kAvx2);
  EXPECT_STREQ(SimdPathName(SimdPath::kAvx512), "avx512");
  EXPECT_THROW(ParseSimdPath("sse9"), Error);
  const std::vector<SimdPath> paths = SupportedSimdPaths();
  ASSERT_FALSE(paths.empty());
  EXPECT_EQ(paths.front(), SimdPath::kBaseline);
  EXPECT_EQ(ActiveSimdPath(), paths.back()) << "the best path is chosen unless SKYFALL_SIMD asks otherwise";
  if (paths.size() < 3) {
    EXPECT_THROW(SetSimdPath(SimdPath::kAvx512), Error);
  }
}

TEST(Rasterizer, EmptyCloudRendersTheBackground) {
  const PinholeCamera cam = LookDownCamera(41.6, 20, 10, 40.0);
  const RenderOutput<float> r = RenderGaussians(GaussianCloudT<float>{}, cam, SmoothRasterOptions());
  EXPECT_FLOAT_EQ(r.rgb[0], 0.2f);
  EXPECT_FLOAT_EQ(r.rgb[2], 0.4f);
  EXPECT_EQ(r.alpha[0], 0.0f);
}

// A non-finite loss gradient at one pixel reaches only the Gaussians that
// blend that pixel. The vector paths process a row in lanes; a Gaussian whose
// footprint shares a lane group with the pixel, but not the pixel, must not
// pick it up (0 * NaN is NaN). Gaussian 1 is 5 px right of the pixel, inside
// one lane group of every path wider than one lane.
TEST(Rasterizer, ANonFiniteLossGradientStaysWithTheGaussiansThatBlendItsPixel) {
  PinholeCamera cam = LookDownCamera(40.0, 16, 16, 40.0);
  cam.cam_from_world_rotation << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * Eigen::Vector3d(0, 0, 40);
  cam.cx = cam.cy = 7.5;  // 1 m on the ground = 1 px; u = 7.5 + east, v = 7.5 - north
  Cloud c;
  c.resize(2);
  c.means[0] = Eigen::Vector3d(-5.5, 0, 0);  // u = 2
  c.means[1] = Eigen::Vector3d(-1.5, 0, 0);  // u = 6: footprint from u = 3
  for (int i = 0; i < 2; ++i) {
    c.log_scales[i] = Eigen::Vector3d::Constant(std::log(0.4));
    c.rotations[i] = Eigen::Vector4d(1, 0, 0, 0);
    c.opacity_logits[i] = 2.0;
    c.sh[i].fill(0.1);
  }
  const GaussianCloudT<float> cloud = testing::ToFloat(c);
  const std::size_t n = 16 * 16, bad = 8 * 16 + 1;  // pixel (1, 8)
  std::vector<float> d_rgb(3 * n, 0.5f), d_alpha(n, 0.2f), d_depth(n, 0.1f);
  for (SimdPath path : SupportedSimdPaths()) {
    SCOPED_TRACE(SimdPathName(path));
    ScopedSimdPath scoped(path);
    const RenderOutput<float> r = RenderGaussians(cloud, cam, RasterOptions{});
    ASSERT_GT(r.alpha[bad], 0.1f);  // Gaussian 0 blends it
    const GaussianGradients<float> clean = BackwardGaussians(cloud, cam, RasterOptions{}, r, d_rgb, d_alpha, d_depth);
    std::vector<float> nan_rgb = d_rgb, nan_alpha = d_alpha, nan_depth = d_depth;
    for (int ch = 0; ch < 3; ++ch) nan_rgb[3 * bad + ch] = std::numeric_limits<float>::quiet_NaN();
    nan_alpha[bad] = nan_depth[bad] = std::numeric_limits<float>::quiet_NaN();
    const GaussianGradients<float> g = BackwardGaussians(cloud, cam, RasterOptions{}, r, nan_rgb, nan_alpha, nan_depth);
    EXPECT_FALSE(std::isfinite(g.d.means[0].sum()));  // it blends the pixel: its gradient is lost
    EXPECT_GT(clean.d.means[1].norm(), 0.0f);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(g.d.means[1][k], clean.d.means[1][k]) << k;
      EXPECT_EQ(g.d.log_scales[1][k], clean.d.log_scales[1][k]) << k;
    }
    for (int k = 0; k < 12; ++k) EXPECT_EQ(g.d.sh[1][k], clean.d.sh[1][k]) << k;
    EXPECT_EQ(g.d.opacity_logits[1], clean.d.opacity_logits[1]);
  }
}

TEST(Rasterizer, OpaqueGaussianCoversItsPixelAndGivesItsDepth) {
  // One flat, wide, opaque Gaussian at height 5 m seen from 40 m: expected
  // depth 35 m in the middle, alpha ~ its opacity.
  PinholeCamera cam = LookDownCamera(41.6, 16, 16, 40.0);
  cam.cam_from_world_rotation << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * Eigen::Vector3d(0, 0, 40);
  cam.cx = cam.cy = 7.5;
  GaussianCloudT<double> c;
  c.resize(1);
  c.means[0] = Eigen::Vector3d(0, 0, 5);
  c.log_scales[0] = Eigen::Vector3d(std::log(50.0), std::log(50.0), std::log(0.01));
  c.rotations[0] = Eigen::Vector4d(1, 0, 0, 0);
  c.opacity_logits[0] = 3.0;
  c.sh[0].fill(0.0);
  c.sh[0][0] = ShDcFromColour(0.8);
  const RenderOutput<double> r = RenderGaussians(c, cam, RasterOptions{});
  const std::size_t mid = 8 * 16 + 8;
  EXPECT_NEAR(r.alpha[mid], 1.0 / (1.0 + std::exp(-3.0)), 1e-3);
  EXPECT_NEAR(r.depth[mid] + r.reference_depth_m, 35.0, 1e-6);
  EXPECT_NEAR(r.rgb[3 * mid], 0.8 * r.alpha[mid], 1e-3);
}

TEST(Rasterizer, MedianDepthIsWhereOpacityReachesOneHalf) {
  // A faint wide floater (opacity 0.3) at 30 m above an opaque roof (0.95)
  // at 5 m, seen from 40 m: the expected depth is pulled towards the floater,
  // the median depth is the roof's. A third, lone faint Gaussian off to the
  // side never reaches 0.5: no median depth there.
  PinholeCamera cam = LookDownCamera(41.6, 32, 16, 40.0);
  cam.cam_from_world_rotation << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * Eigen::Vector3d(0, 0, 40);
  cam.cx = 7.5;
  cam.cy = 7.5;
  auto logit = [](double a) { return std::log(a / (1 - a)); };
  GaussianCloudT<double> c;
  c.resize(3);
  const double heights[] = {30.0, 5.0, 5.0}, opacities[] = {0.3, 0.95, 0.3};
  const Eigen::Vector3d centres[] = {{0, 0, 30}, {0, 0, 5}, {16, 0, 5}};
  for (int i = 0; i < 3; ++i) {
    c.means[i] = centres[i];
    c.log_scales[i] = Eigen::Vector3d(std::log(3.0), std::log(3.0), std::log(0.01));
    c.rotations[i] = Eigen::Vector4d(1, 0, 0, 0);
    c.opacity_logits[i] = logit(opacities[i]);
    c.sh[i].fill(0.0);
    EXPECT_EQ(c.means[i].z(), heights[i]);
  }
  RasterOptions o;
  EXPECT_TRUE(RenderGaussians(c, cam, o).median_depth.empty()) << "off unless asked for";
  o.median_depth = true;
  const RenderOutput<double> r = RenderGaussians(c, cam, o);
  const std::size_t mid = 8 * 32 + 8, side = 8 * 32 + 24;
  ASSERT_GT(r.alpha[mid], 0.5);
  EXPECT_NEAR(r.median_depth[mid] + r.reference_depth_m, 35.0, 1e-9);
  const double expected = r.depth[mid] + r.reference_depth_m;
  EXPECT_GT(expected, 10.0 + 1.0);  // between the two, clearly off the roof
  EXPECT_LT(expected, 35.0 - 1.0);
  ASSERT_LT(r.alpha[side], 0.5);
  EXPECT_TRUE(std::isnan(r.median_depth[side]));
}

}  // namespace
}  // namespace skyfall
