#include "merge/stitch.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/error.h"
#include "merge/dsm.h"
#include "merge/seam.h"

namespace skyfall {
namespace {

// A 2 x 2 tiling of a 128 m square city centred on the frame origin.
constexpr double kTileM = 64.0, kOverlapM = 8.0;
const GeodeticPoint kCityOrigin{-81.6637, 30.3488, 10.0};

TileGrid TestGrid() {
  TileGrid g;
  g.origin_m = {-64.0, -64.0};
  g.tile_m = kTileM;
  g.overlap_m = kOverlapM;
  g.cols = g.rows = 2;
  return g;
}

std::vector<TileSpec> TestTiles() {
  const TileGrid g = TestGrid();
  GroundBox bounds;
  bounds.min_m = {-64, -64};
  bounds.max_m = {64, 64};
  std::vector<TileSpec> tiles;
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 2; ++col) {
      TileSpec t;
      t.id = "T_c" + std::to_string(col) + "_r" + std::to_string(row);
      t.col = col, t.row = row, t.grid = g;
      t.core = g.Core(col, row);
      t.extent.min_m = (t.core.min_m.array() - kOverlapM).max(-64.0);
      t.extent.max_m = (t.core.max_m.array() + kOverlapM).min(64.0);
      t.enu_origin = kCityOrigin;
      tiles.push_back(t);
    }
  }
  return tiles;
}

double Surface(double x, double y) { return 3.0 * std::sin(x / 10.0) * std::cos(y / 13.0); }

// Opaque Gaussians on a 0.5 m lattice of a hilly surface.
GaussianCloud SurfaceCloud() {
  GaussianCloud c;
  for (double y = -63.75; y < 64; y += 0.5) {
    for (double x = -63.75; x < 64; x += 0.5) {
      c.means.emplace_back(x, y, Surface(x, y));
      c.log_scales.emplace_back(Eigen::Vector3f::Constant(std::log(0.35f)));
      c.rotations.emplace_back(1, 0, 0, 0);
      c.opacity_logits.push_back(2.2f);  // 0.9
      std::array<float, 12> sh{};
      sh[0] = sh[4] = sh[8] = 0.5f;
      sh[11] = static_cast<float>(c.sh.size());  // identity tag: its index (exact in float below 2^24)
      c.sh.push_back(sh);
    }
  }
  return c;
}

// What a tile "reconstructs": the truth Gaussians inside its extent, with
// its own jitter (independent reconstructions never agree exactly).
GaussianCloud TileView(const GaussianCloud& truth, const TileSpec& t, double jitter_m, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(jitter_m));
  GaussianCloud out;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (!t.extent.Contains(truth.means[i].x(), truth.means[i].y())) continue;
    out.Append(truth, i);
    if (jitter_m > 0) out.means.back() += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
  }
  return out;
}

std::vector<TileCloud> Reconstruct(const GaussianCloud& truth, double jitter_m) {
  std::vector<TileCloud> tiles;
  std::uint64_t seed = 1;
  for (const TileSpec& t : TestTiles()) tiles.push_back({t, TileView(truth, t, jitter_m, seed++)});
  return tiles;
}

std::vector<std::array<float, 3>> SortedMeans(const GaussianCloud& c) {
  std::vector<std::array<float, 3>> v;
  for (const auto& p : c.means) v.push_back({p.x(), p.y(), p.z()});
  std::sort(v.begin(), v.end());
  return v;
}

TEST(Stitch, ExactCopiesInTheOverlapAreKeptOnce) {
  const GaussianCloud truth = SurfaceCloud();
  const std::vector<TileCloud> tiles = Reconstruct(truth, 0.0);
  std::size_t total = 0;
  for (const TileCloud& t : tiles) total += t.cloud.size();
  const StitchResult r = StitchTiles(StitchOptions{}, kCityOrigin, tiles);
  // Every Gaussian of the city once, none twice: the merged set is the truth.
  EXPECT_EQ(SortedMeans(r.cloud), SortedMeans(truth));
  EXPECT_EQ(r.kept_in_core, truth.size());
  EXPECT_EQ(r.duplicates_removed, total - truth.size());
  EXPECT_EQ(r.holes_filled, 0u);
  // Each kept Gaussian comes from the tile whose core owns it.
  const TileGrid g = TestGrid();
  for (std::size_t i = 0; i < r.cloud.size(); ++i) {
    const Eigen::Vector2i o = g.Owner(r.cloud.means[i].x(), r.cloud.means[i].y());
    ASSERT_EQ(r.source_tile[i], o.y() * 2 + o.x());
  }
}

TEST(Stitch, IndependentReconstructionsLeaveNoDuplicates) {
  const GaussianCloud truth = SurfaceCloud();
  const StitchResult r = StitchTiles(StitchOptions{}, kCityOrigin, Reconstruct(truth, 0.15));
  // Jittered copies (sigma 0.15 m, within the 1-voxel match radius) in the
  // overlaps are recognised as duplicates: no truth Gaussian is kept twice.
  std::vector<int> copies(truth.size(), 0);
  for (const auto& sh : r.cloud.sh) ++copies[static_cast<std::size_t>(sh[11])];
  // Both tiles keep a Gaussian only when each copy jittered into its own
  // tile's core: then it lies within a few sigma of the core boundary.
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (copies[i] < 2) continue;
    EXPECT_EQ(copies[i], 2);
    const Eigen::Vector3f& p = truth.means[i];
    EXPECT_LT(std::min(std::abs(p.x()), std::abs(p.y())), 4 * 0.15) << p.transpose();
  }
  const auto twice = static_cast<std::size_t>(std::count(copies.begin(), copies.end(), 2));
  EXPECT_LT(twice, truth.size() / 1000);
  // A Gaussian whose two copies both jittered across the core boundary, away
  // from their owners, is dropped by both: rare (expected ~1e-4 here), and
  // its neighbours 0.5 m away still cover the surface.
  const auto lost = static_cast<std::size_t>(std::count(copies.begin(), copies.end(), 0));
  EXPECT_LT(lost, truth.size() / 1000);
  EXPECT_GT(r.duplicates_removed, 0u);
}

TEST(Stitch, OverlapFillsAHoleTheOwnerLeftOnce) {
  const GaussianCloud truth = SurfaceCloud();
  std::vector<TileCloud> tiles = Reconstruct(truth, 0.0);
  // Tile (1, 0) missed a 6 m x 10 m patch of its core right at the boundary
  // with (0, 0), inside (0, 0)'s overlap band (and not in the other tiles').
  auto in_patch = [](const Eigen::Vector3f& p) { return p.x() >= 0 && p.x() < 6 && p.y() >= -40 && p.y() < -30; };
  GaussianCloud holed;
  std::size_t patch = 0;
  for (std::size_t i = 0; i < tiles[1].cloud.size(); ++i) {
    if (in_patch(tiles[1].cloud.means[i])) {
      ++patch;
    } else {
      holed.Append(tiles[1].cloud, i);
    }
  }
  ASSERT_GT(patch, 100u);
  tiles[1].cloud = holed;
  const StitchResult r = StitchTiles(StitchOptions{}, kCityOrigin, tiles);
  // Nothing twice.
  std::vector<int> copies(truth.size(), 0);
  for (const auto& sh : r.cloud.sh) ++copies[static_cast<std::size_t>(sh[11])];
  EXPECT_EQ(*std::max_element(copies.begin(), copies.end()), 1);
  // The hole is filled from the neighbour except a rim as wide as the match
  // radius (1 voxel of 1 m, i.e. up to 2 voxel widths from the cell centre),
  // where the owner's remaining geometry counts as covering it.
  std::size_t filled = 0, rim_lost = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (!in_patch(truth.means[i])) {
      EXPECT_EQ(copies[i], 1);
      continue;
    }
    if (copies[i]) {
      ++filled;
    } else {
      ++rim_lost;
      const Eigen::Vector3f& p = truth.means[i];
      const double to_edge = std::min({p.x() - 0.0f, 6.0f - p.x(), p.y() + 40.0f, -30.0f - p.y()});
      EXPECT_LT(to_edge, 2.0) << "lost Gaussian deep inside the hole at " << p.transpose();
    }
  }
  EXPECT_EQ(r.holes_filled, filled);
  EXPECT_GT(filled, patch / 4);
  EXPECT_EQ(filled + rim_lost, patch);
}

TEST(Stitch, TilesInAnotherFrameAreBroughtIntoTheCityFrame) {
  const GaussianCloud truth = SurfaceCloud();
  std::vector<TileCloud> tiles = Reconstruct(truth, 0.0);
  // The tiles were planned and reconstructed in a frame 2 km east, 1 km north.
  const GeodeticPoint tile_origin{-81.6430, 30.3578, 25.0};
  const Eigen::Isometry3d tile_from_city = FrameChange(kCityOrigin, tile_origin);
  // A rigid map: rotation orthonormal, and the origin lands ~2.2 km away.
  EXPECT_NEAR((tile_from_city.linear() * tile_from_city.linear().transpose() - Eigen::Matrix3d::Identity()).norm(), 0, 1e-12);
  EXPECT_NEAR(tile_from_city.translation().head<2>().norm(), 2230, 100);
  // Round trip through the two frames is exact to round-off.
  const Eigen::Isometry3d back = FrameChange(tile_origin, kCityOrigin) * tile_from_city;
  EXPECT_LT((back.matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-8);  // 10 nm at 2 km

  const GaussianCloud moved = TransformCloud(truth, tile_from_city);
  const GaussianCloud returned = TransformCloud(moved, FrameChange(tile_origin, kCityOrigin));
  for (std::size_t i = 0; i < truth.size(); i += 97) {
    ASSERT_LT((returned.means[i] - truth.means[i]).norm(), 2e-3f);  // float at 2 km: 0.25 mm steps
  }
  // The degree-1 SH term seen along a direction equals the moved cloud's
  // term seen along the rotated direction.
  GaussianCloud one;
  one.Append(truth, 0);
  one.sh[0] = {0.1f, 0.3f, -0.2f, 0.7f, 0, 0, 0, 0, 0, 0, 0, 0};
  const GaussianCloud one_moved = TransformCloud(one, tile_from_city);
  const Eigen::Vector3d dir = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  auto term = [](const std::array<float, 12>& sh, const Eigen::Vector3d& d) {
    return -d.y() * sh[1] + d.z() * sh[2] - d.x() * sh[3];
  };
  EXPECT_NEAR(term(one.sh[0], dir), term(one_moved.sh[0], tile_from_city.linear() * dir), 1e-6);
  EXPECT_NE(one.sh[0][1], one_moved.sh[0][1]);  // the rotation (0.01 deg) is not the identity
}

TEST(Stitch, GridsOfDifferentTilingsAreRefused) {
  std::vector<TileCloud> tiles = Reconstruct(SurfaceCloud(), 0.0);
  tiles[2].tile.grid.tile_m = 32;
  EXPECT_THROW(StitchTiles(StitchOptions{}, kCityOrigin, tiles), Error);
  EXPECT_THROW(StitchTiles(StitchOptions{}, kCityOrigin, {}), Error);
}

TEST(SeamMetric, FlagsAStepBetweenTilesAndNotAConsistentMerge) {
  const GaussianCloud truth = SurfaceCloud();
  std::vector<TileCloud> tiles = Reconstruct(truth, 0.0);
  GroundBox bounds;
  bounds.min_m = {-60, -60};  // inside the cloud: no empty rim
  bounds.max_m = {60, 60};
  auto seam_of = [&](const std::vector<TileCloud>& t) {
    const StitchResult r = StitchTiles(StitchOptions{}, kCityOrigin, t);
    DsmGrid dsm = GridCovering(bounds, kCityOrigin, 32617, 0.5);
    RasterizeDsm(r.cloud, kCityOrigin, DsmExportOptions{}, &dsm);
    return MeasureSeams(dsm, TestGrid(), kCityOrigin);
  };
  const SeamMetric clean = seam_of(tiles);
  EXPECT_GT(clean.boundary_pairs, 400u);  // two boundary lines of 240 px
  EXPECT_GT(clean.interior_pairs, 50000u);
  // A consistent merge has boundary steps like any others (hills: ~0.1 m).
  EXPECT_LT(clean.ratio, 1.5);
  EXPECT_GT(clean.ratio, 0.5);
  // Tile (1, 1) reconstructed 1.5 m too high: the seam shows.
  for (auto& p : tiles[3].cloud.means) p.z() += 1.5f;
  const SeamMetric stepped = seam_of(tiles);
  // Measured 2.2 on the default (median-depth) DSM, against 0.9 clean;
  // above 3 on an expected-depth DSM.
  EXPECT_GT(stepped.ratio, 2.0);
  EXPECT_NEAR(stepped.interior_mean_step_m, clean.interior_mean_step_m, 0.02);
}

}  // namespace
}  // namespace skyfall
