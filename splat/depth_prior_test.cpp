#include "splat/depth_prior.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

TEST(DepthPrior, SurfaceOfAFlatGroundGivesRayPlaneDepths) {
  // Points on z = 5 m over 200 m x 200 m, with a hole in the middle.
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-100, 100);
  std::vector<Eigen::Vector3f> pts;
  while (pts.size() < 4000) {
    const float x = u(rng), y = u(rng);
    if (std::abs(x) < 10 && std::abs(y) < 10) continue;
    pts.emplace_back(x, y, 5.0f);
  }
  SurfaceDepthPrior prior(pts, 2.0);
  EXPECT_NEAR(prior.HeightAt(0.5, 0.5), 5.0, 1e-6);  // the hole is filled
  PseudoCameraOptions o;
  o.look_at_sigma_m = 10;
  o.radius_m = 120;  // the view stays over the 200 m square
  o.size_px = 48;
  const PinholeCamera cam = SamplePseudoCamera(o, Eigen::Vector3d(0, 0, 5), 7);
  const DepthMap m = prior.Estimate(cam, {});
  int valid = 0;
  const Eigen::Vector3d c = cam.Centre();
  for (int r = 0; r < cam.height_px; ++r)
    for (int col = 0; col < cam.width_px; ++col) {
      const size_t p = static_cast<size_t>(r) * cam.width_px + col;
      if (!m.valid[p]) continue;
      ++valid;
      const double yn = (r - cam.cy) / cam.fy;
      const Eigen::Vector3d d = cam.cam_from_world_rotation.transpose() * Eigen::Vector3d((col - cam.cx) / cam.fx, yn, 1);
      const double t = (5.0 - c.z()) / d.z();  // exact ray-plane depth
      EXPECT_NEAR(m.depth[p], t, 0.01) << col << "," << r;
    }
  EXPECT_GT(valid, cam.width_px * cam.height_px / 2);
}

TEST(DepthPrior, NadirViewsOfAStepSeeBothLevelsAtTheirDepths) {
  // Ground at 0 m west of x = 0, a 30 m roof east of it: 1 m grid of points.
  std::vector<Eigen::Vector3f> pts;
  for (int i = -60; i <= 60; ++i)
    for (int j = -60; j <= 60; ++j) pts.emplace_back(i + 0.5f, j + 0.5f, i >= 0 ? 30.0f : 0.0f);
  const SurfaceDepthPrior prior(pts, 1.0);
  const double height_m = 1.0e5, gsd_m = 0.5;
  const PinholeCamera cam = NadirCamera(Eigen::Vector3d(0, 0, 0), gsd_m, 64, height_m);
  // Geometry: east is +col, north is -row, a pixel is gsd_m on the ground.
  const Eigen::Vector2d centre = cam.Project(Eigen::Vector3d(0, 0, 0));
  EXPECT_NEAR(centre.x(), 31.5, 1e-9);
  EXPECT_NEAR(centre.y(), 31.5, 1e-9);
  EXPECT_NEAR(cam.Project(Eigen::Vector3d(gsd_m, gsd_m, 0)).x() - centre.x(), 1.0, 1e-6);
  EXPECT_NEAR(cam.Project(Eigen::Vector3d(gsd_m, gsd_m, 0)).y() - centre.y(), -1.0, 1e-6);
  const double reference = cam.cam_from_world_translation.z();
  const DepthMap nadir = prior.NadirDepthRelativeTo(cam, reference);
  const DepthMap marched = prior.DepthRelativeTo(cam, reference);
  for (int col : {2, 20, 45, 61}) {
    const std::size_t p = static_cast<std::size_t>(32) * 64 + col;
    ASSERT_TRUE(nadir.valid[p]);
    // Relative to the frame origin's depth: 0 on the ground, -30 m on the roof
    // (the step itself, at col ~31.5, is left out).
    EXPECT_NEAR(nadir.depth[p], col > 32 ? -30.0 : 0.0, 1e-3) << col;
    EXPECT_NEAR(nadir.depth[p], marched.depth[p], 0.05) << col;  // the march's bisection tolerance
  }
}

// The first crossing of a ray with the surface found by a fine march (a
// fiftieth of a cell per step) and bisection: slow, but simple enough to
// trust as the reference for the cell walk.
double FineMarchDepth(const SurfaceDepthPrior& prior, const Eigen::Vector3d& c, const Eigen::Vector3d& d,
                      double cell_m, double top_m, double bottom_m) {
  const double dt = cell_m / 50.0 / d.norm();
  auto below = [&](double t) {
    const Eigen::Vector3d p = c + t * d;
    const double h = prior.HeightAt(p.x(), p.y());
    return std::isfinite(h) && p.z() <= h;
  };
  const double t_end = (bottom_m - c.z()) / d.z();  // below every height: nothing more to meet
  for (double t = (top_m - c.z()) / d.z(), prev = t; t <= t_end; prev = t, t += dt) {
    if (!below(t)) continue;
    double a = prev, b = t;
    for (int k = 0; k < 30; ++k) (below(0.5 * (a + b)) ? b : a) = 0.5 * (a + b);
    return b;
  }
  return NAN;
}

TEST(DepthPrior, CellWalkMeetsRoofsAndWallsWhereAFineMarchDoes) {
  // Blocks of random height (0-40 m) and single-cell spikes on a 0.5 m grid
  // (the walk skips whole blocks of 8 x 8 cells the ray passes above), seen obliquely at 45
  // and 70 deg: every pixel's depth equals the fine march's, except where the
  // march's steps cut a cell corner it then misses (the walk cannot miss one:
  // it visits every cell on the ray's path), so it is never farther.
  const double cell_m = 0.5;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> block_height(0.0f, 40.0f);
  std::vector<float> blocks(16 * 16);
  for (float& b : blocks) b = block_height(rng) < 16.0f ? 0.0f : block_height(rng);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 256; ++i)
    for (int j = 0; j < 256; ++j)
      pts.emplace_back(-64 + (i + 0.5f) * cell_m, -64 + (j + 0.5f) * cell_m,
                       block_height(rng) < 1.0f ? block_height(rng) : blocks[(j / 16) * 16 + i / 16]);  // 2.5% spikes
  const SurfaceDepthPrior prior(pts, cell_m);
  for (double elevation_deg : {45.0, 70.0}) {
    PseudoCameraOptions o;
    o.min_elevation_deg = o.max_elevation_deg = elevation_deg;
    o.look_at_sigma_m = 5;
    o.radius_m = 150;
    o.size_px = 64;
    const PinholeCamera cam = SamplePseudoCamera(o, Eigen::Vector3d(0, 0, 0), 11);
    const DepthMap walked = prior.DepthRelativeTo(cam, 0.0);
    const Eigen::Vector3d c = cam.Centre();
    int both = 0, agree = 0;
    for (int r = 0; r < cam.height_px; ++r)
      for (int col = 0; col < cam.width_px; ++col) {
        const std::size_t p = static_cast<std::size_t>(r) * cam.width_px + col;
        const double yn = (r - cam.cy) / cam.fy;
        const Eigen::Vector3d d = cam.cam_from_world_rotation.transpose() * Eigen::Vector3d((col - cam.cx) / cam.fx, yn, 1);
        const double fine = FineMarchDepth(prior, c, d, cell_m, 41.0, -1.0);
        ASSERT_EQ(static_cast<bool>(walked.valid[p]), std::isfinite(fine)) << elevation_deg << " deg, " << col << "," << r;
        if (!walked.valid[p]) continue;
        ++both;
        // Tolerance: the march's step, 1/50 of a cell along the ray.
        const double step_m = cell_m / 50.0 / d.norm();
        EXPECT_LE(walked.depth[p], fine + step_m) << elevation_deg << " deg, " << col << "," << r;
        if (std::abs(walked.depth[p] - fine) <= step_m) ++agree;
      }
    EXPECT_GT(both, 64 * 64 / 2) << elevation_deg;  // most of the view lies on the grid
    EXPECT_GE(agree, both * 995 / 1000) << elevation_deg << " deg: " << both - agree << " of " << both << " differ";
  }
}

TEST(DepthPrior, DenseCellCentresKeepTheirOwnCellsAndTheEdgeOfARoof) {
  // The dense heights' layout: one point per 0.5 m cell centre, written with
  // three decimals and read back as float, whose rounding puts some points a
  // hair short of their lattice position. A 20 m roof covers x >= 3 m.
  const double cell_m = 0.5, first_m = -64.418;
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 200; ++i)
    for (int j = 0; j < 40; ++j) {
      const double x = std::round((first_m + i * cell_m) * 1e3) / 1e3, y = std::round((5.291 + j * cell_m) * 1e3) / 1e3;
      pts.emplace_back(static_cast<float>(x), static_cast<float>(y), x >= 3.0 ? 20.0f : 0.0f);
    }
  const SurfaceDepthPrior prior(pts, cell_m);
  // Anywhere within a point's cell (0.24 m either way) the height is its own.
  for (const Eigen::Vector3f& p : pts)
    for (double dx : {-0.24, 0.0, 0.24})
      for (double dy : {-0.24, 0.0, 0.24})
        ASSERT_EQ(prior.HeightAt(p.x() + dx, p.y() + dy), p.z()) << p.x() << "+" << dx << "," << p.y() << "+" << dy;
  // The cell boundary between the last ground point (x = 2.582) and the
  // first roof point (3.082) is halfway, at 2.832 m.
  EXPECT_EQ(prior.HeightAt(2.82, 6.0), 0.0);
  EXPECT_EQ(prior.HeightAt(2.84, 6.0), 20.0);
  EXPECT_TRUE(prior.DepthRelativeTo(NadirCamera(Eigen::Vector3d(0, 12, 0), 0.5, 16, 1e5), 0.0).weight.empty());

  // Point weights (filled roof cells at 0.25): a nadir view returns the
  // weight of the cell each ray meets, the depth as without weights.
  std::vector<float> weights(pts.size());
  for (std::size_t k = 0; k < pts.size(); ++k) weights[k] = pts[k].z() > 10 ? 0.25f : 1.0f;
  EXPECT_THROW(SurfaceDepthPrior(pts, cell_m, std::vector<float>(3, 1.0f)), Error);
  const SurfaceDepthPrior weighted(pts, cell_m, weights);
  EXPECT_EQ(weighted.WeightAt(2.82, 6.0), 1.0f);
  EXPECT_EQ(weighted.WeightAt(2.84, 6.0), 0.25f);
  EXPECT_EQ(weighted.WeightAt(500.0, 6.0), 0.0f);  // outside
  const PinholeCamera cam = NadirCamera(Eigen::Vector3d(2.832, 12.0, 0), 0.5, 16, 1e5);
  const double reference = cam.cam_from_world_translation.z();
  const DepthMap plain = prior.NadirDepthRelativeTo(cam, reference);
  const DepthMap nadir = weighted.NadirDepthRelativeTo(cam, reference);
  ASSERT_EQ(nadir.weight.size(), nadir.depth.size());
  int roof = 0, ground = 0;
  for (std::size_t p = 0; p < nadir.depth.size(); ++p) {
    ASSERT_TRUE(nadir.valid[p]);
    EXPECT_EQ(nadir.depth[p], plain.depth[p]);
    const bool on_roof = nadir.depth[p] < -10;
    EXPECT_EQ(nadir.weight[p], on_roof ? 0.25f : 1.0f) << p;
    (on_roof ? roof : ground) += 1;
  }
  EXPECT_GT(roof, 0);
  EXPECT_GT(ground, 0);
}

TEST(DepthPrior, PseudoCamerasLookDownAtTheSceneFromTheRequestedRange) {
  const PseudoCameraOptions o;
  for (std::uint64_t s = 0; s < 20; ++s) {
    const PinholeCamera cam = SamplePseudoCamera(o, Eigen::Vector3d(10, -20, 3), s);
    const Eigen::Vector3d f = cam.cam_from_world_rotation.row(2).transpose();
    const double elevation = std::asin(-f.z()) * 180 / M_PI;
    EXPECT_GE(elevation, o.min_elevation_deg - 1e-9);
    EXPECT_LE(elevation, o.max_elevation_deg + 1e-9);
    EXPECT_NEAR(cam.Centre().z() - 3.0, o.radius_m * std::sin(elevation * M_PI / 180), 1e-6);
  }
}

TEST(DepthPrior, ExternalCommandIsPluggable) {
  // Any program that writes a depth raster for the view works; here GDAL
  // turns the view's red channel into the "depth".
  const fs::path dir = ScratchDir("cmd");
  CommandDepthPrior prior("gdal_translate -q -ot Float32 -b 1 {in} {out}", dir.string());
  PinholeCamera cam;
  cam.width_px = 8;
  cam.height_px = 6;
  std::vector<float> rgb(8 * 6 * 3, 0.0f);
  for (int k = 0; k < 8 * 6; ++k) rgb[3 * k] = k / 100.0f;
  const DepthMap m = prior.Estimate(cam, rgb);
  ASSERT_EQ(m.depth.size(), 48u);
  EXPECT_FLOAT_EQ(m.depth[10], std::round(0.10f * 255.0f));
  EXPECT_EQ(m.valid[0], 1);
  EXPECT_THROW(CommandDepthPrior("echo no placeholders", dir.string()), Error);
  CommandDepthPrior failing("false {in} {out}", dir.string());
  EXPECT_THROW(failing.Estimate(cam, rgb), Error);
}

}  // namespace
}  // namespace skyfall
