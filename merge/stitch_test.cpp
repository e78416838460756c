#include "merge/stitch.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/error.h"
#include "products/dsm.h"
#include "merge/seam.h"

namespace skyfall {
namespace {

// A tiling of 64 m tiles (2 x 2 by default: a 128 m square city centred on
// the frame origin), its lower-left corner at (-64, -64).
constexpr double kTileM = 64.0, kOverlapM = 8.0;
const GeodeticPoint kCityOrigin{-81.6637, 30.3488, 10.0};

TileGrid TestGrid(int cols = 2, int rows = 2) {
  TileGrid g;
  g.origin_m = {-64.0, -64.0};
  g.tile_m = kTileM;
  g.overlap_m = kOverlapM;
  g.cols = cols;
  g.rows = rows;
  return g;
}

std::vector<TileSpec> TestTiles(int cols = 2, int rows = 2) {
  const TileGrid g = TestGrid(cols, rows);
  const Eigen::Array2d lo(-64, -64), hi(-64 + cols * kTileM, -64 + rows * kTileM);
  std::vector<TileSpec> tiles;
  for (int row = 0; row < rows; ++row) {
    for (int col = 0; col < cols; ++col) {
      TileSpec t;
      t.id = "T_c" + std::to_string(col) + "_r" + std::to_string(row);
      t.col = col, t.row = row, t.grid = g;
      t.core = g.Core(col, row);
      t.extent.min_m = (t.core.min_m.array() - kOverlapM).max(lo);
      t.extent.max_m = (t.core.max_m.array() + kOverlapM).min(hi);
      t.enu_origin = kCityOrigin;
      tiles.push_back(t);
    }
  }
  return tiles;
}

double Surface(double x, double y) { return 3.0 * std::sin(x / 10.0) * std::cos(y / 13.0); }

// Opaque Gaussians on a 0.5 m lattice of a hilly surface.
GaussianCloud SurfaceCloud(int cols = 2, int rows = 2) {
  GaussianCloud c;
  for (double y = -63.75; y < -64 + rows * kTileM; y += 0.5) {
    for (double x = -63.75; x < -64 + cols * kTileM; x += 0.5) {
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

std::vector<TileCloud> Reconstruct(const GaussianCloud& truth, double jitter_m, int cols = 2, int rows = 2) {
  std::vector<TileCloud> tiles;
  std::uint64_t seed = 1;
  for (const TileSpec& t : TestTiles(cols, rows)) tiles.push_back({t, TileView(truth, t, jitter_m, seed++)});
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
  // Straight core boundaries: the seam lines would follow the jitter, and
  // this test is about duplicates near a known boundary.
  StitchOptions straight;
  straight.seam_lines.enabled = false;
  const StitchResult r = StitchTiles(straight, kCityOrigin, Reconstruct(truth, 0.15));
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
    return MeasureSeams(dsm, r.ownership, kCityOrigin);
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
  // Border by border, the step shows on the two borders of tile (1, 1)
  // alone. A border's step is measured across it only, so on hills it
  // differs from the interior's (which mixes both directions): each border
  // is compared with itself before the raise. The median-depth DSM spreads
  // the 1.5 m raise over the few pixels its metre-wide Gaussians cover, so
  // a pair's step is a part of it: the raised borders' mean step grows by
  // 0.11-0.27 m (measured), the others' by about 0.01 m; the bounds sit
  // between, 2x from each. 2 x 2 tiles have 4 borders; diagonal neighbours
  // touch at a corner through a few pixel pairs and are not judged.
  ASSERT_EQ(stepped.borders.size(), clean.borders.size());
  int judged = 0;
  for (std::size_t k = 0; k < stepped.borders.size(); ++k) {
    const BorderSeam& b = stepped.borders[k];
    ASSERT_EQ(b.tile_a, clean.borders[k].tile_a);
    ASSERT_EQ(b.tile_b, clean.borders[k].tile_b);
    if (b.pairs < 100) continue;
    ++judged;
    const double grown_m = b.mean_step_m - clean.borders[k].mean_step_m;
    if (b.tile_b == Eigen::Vector2i(1, 1)) {
      EXPECT_GT(grown_m, 0.05) << b.tile_a.transpose() << " | " << b.tile_b.transpose();
    } else {
      EXPECT_LT(grown_m, 0.025) << b.tile_a.transpose() << " | " << b.tile_b.transpose();
    }
  }
  EXPECT_EQ(judged, 4);
}

// Tile (1, 0) raised a patch 4 m that straddles its boundary with (0, 0)
// (x in [-3, 2), y in [-40, -20)): a roof edge it placed too far out.
std::vector<TileCloud> WithAWrongPatch(const GaussianCloud& truth) {
  std::vector<TileCloud> tiles = Reconstruct(truth, 0.0);
  for (Eigen::Vector3f& p : tiles[1].cloud.means)
    if (p.x() >= -3 && p.x() < 2 && p.y() >= -40 && p.y() < -20) p.z() += 4.0f;
  return tiles;
}

std::size_t WrongByMoreThan(const GaussianCloud& merged, double tolerance_m) {
  std::size_t wrong = 0;
  for (const Eigen::Vector3f& p : merged.means) wrong += std::abs(p.z() - Surface(p.x(), p.y())) > tolerance_m;
  return wrong;
}

TEST(SeamLines, StayOnTheCoreBoundariesWhereTilesAgree) {
  const StitchResult r = StitchTiles(StitchOptions{}, kCityOrigin, Reconstruct(SurfaceCloud(), 0.0));
  EXPECT_EQ(r.ownership.lines(), 4u);  // two boundaries, each split in two by the other
  EXPECT_EQ(r.ownership.MeanDeviationM(), 0.0);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> coord(-64, 64);
  for (int k = 0; k < 20000; ++k) {
    const double x = coord(rng), y = coord(rng);
    ASSERT_EQ(r.ownership.Owner(x, y), TestGrid().Owner(x, y)) << x << " " << y;
  }
}

TEST(SeamLines, GoAroundWhereOneTileIsWrong) {
  const GaussianCloud truth = SurfaceCloud();
  StitchOptions straight;
  straight.seam_lines.enabled = false;
  const StitchResult cut = StitchTiles(straight, kCityOrigin, WithAWrongPatch(truth));
  // Straight: the wrong tile keeps x in [0, 2) of the patch, 4 x 40
  // Gaussians of the 0.5 m lattice (the rest of it is the neighbour's
  // ground, which the owner covers: duplicates by column).
  EXPECT_EQ(WrongByMoreThan(cut.cloud, 1.0), 160u);
  // By voxel, the wrong tile's raised ground in x in [-3, -1.5) (its
  // overlap) is no duplicate of the owner's ground 4 m below: kept too, 3 x
  // 40 more (nearer x = 0 it lies within the match radius of its own raised
  // core, and goes).
  StitchOptions voxels = straight;
  voxels.occupancy_columns = false;
  EXPECT_EQ(WrongByMoreThan(StitchTiles(voxels, kCityOrigin, WithAWrongPatch(truth)).cloud, 1.0), 160u + 120u);
  const StitchResult bent = StitchTiles(StitchOptions{}, kCityOrigin, WithAWrongPatch(truth));
  // The line goes round the patch on its nearer side: 2 m into the wrong
  // tile's core rather than 3 m into the other's (the band reaches 4 m,
  // half the 8 m margin). Here that leaves the patch to the tile that got
  // it right; which tile is right the merge cannot know, and the nearer
  // side keeps each tile closest to its own core.
  EXPECT_EQ(WrongByMoreThan(bent.cloud, 1.0), 0u);
  for (double y = -39.75; y < -20; y += 0.5) EXPECT_EQ(bent.ownership.Owner(1.75, y), Eigen::Vector2i(0, 0)) << y;
  EXPECT_EQ(bent.ownership.Owner(1.75, 10.0), Eigen::Vector2i(1, 1));  // elsewhere still straight
  EXPECT_EQ(bent.ownership.Owner(-0.25, -60.0), Eigen::Vector2i(0, 0));
  EXPECT_EQ(bent.ownership.Owner(0.25, -60.0), Eigen::Vector2i(1, 0));
  EXPECT_GT(bent.ownership.MeanDeviationM(), 0.0);
}

TEST(SeamLines, EveryPointHasOneOwnerThatReconstructedIt) {
  // Noisy tiles (0.5 m) make the lines wander all over their bands.
  const std::vector<TileCloud> tiles = Reconstruct(SurfaceCloud(), 0.5);
  const TileOwnership own = PlanSeamLinesOnCentres(SeamLineOptions{}, tiles);
  EXPECT_GT(own.MeanDeviationM(), 0.2);
  const std::vector<TileSpec> specs = TestTiles();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> coord(-64, 64);
  for (int k = 0; k < 50000; ++k) {
    const double x = coord(rng), y = coord(rng);
    const Eigen::Vector2i o = own.Owner(x, y);
    ASSERT_TRUE(o.x() >= 0 && o.x() < 2 && o.y() >= 0 && o.y() < 2);
    const TileSpec& t = specs[static_cast<std::size_t>(o.y()) * 2 + o.x()];
    ASSERT_TRUE(t.extent.Contains(x, y)) << x << " " << y << " given to " << t.id;
    // Within half the margin (the band) of its core.
    ASSERT_LE(std::max({t.core.min_m.x() - x, x - t.core.max_m.x(), t.core.min_m.y() - y, y - t.core.max_m.y()}),
              0.5 * kOverlapM + 1e-9);
  }
}

TEST(SeamLines, ABoundaryWithAMissingTileStaysStraight) {
  std::vector<TileCloud> tiles = WithAWrongPatch(SurfaceCloud());
  tiles.erase(tiles.begin());  // tile (0, 0) did not finish
  const TileOwnership own = PlanSeamLinesOnCentres(SeamLineOptions{}, tiles);
  EXPECT_EQ(own.lines(), 2u);  // (1, 0)-(1, 1) and (0, 1)-(1, 1)
  EXPECT_EQ(own.Owner(1.75, -30.0), Eigen::Vector2i(1, 0));
}

TEST(SeamLines, EachLineServesItsOwnBoundaryOnA3x3Grid) {
  // Tile (1, 1) raised two patches over its core's edges: one across its
  // boundary with (0, 1) (x = 0), one across that with (1, 0) (y = 0). On
  // a 3 x 3 grid these two lines' indices differ from those of the other
  // convention (row-major for columns, column-major for rows).
  const GaussianCloud truth = SurfaceCloud(3, 3);
  std::vector<TileCloud> tiles = Reconstruct(truth, 0.0, 3, 3);
  for (Eigen::Vector3f& p : tiles[4].cloud.means) {
    const bool across_x = p.x() >= -3 && p.x() < 2 && p.y() >= 20 && p.y() < 40;
    const bool across_y = p.y() >= -3 && p.y() < 2 && p.x() >= 20 && p.x() < 40;
    if (across_x || across_y) p.z() += 4.0f;
  }
  const StitchResult r = StitchTiles(StitchOptions{}, kCityOrigin, tiles);
  EXPECT_EQ(r.ownership.lines(), 12u);
  EXPECT_EQ(WrongByMoreThan(r.cloud, 1.0), 0u);
  EXPECT_EQ(r.ownership.Owner(1.75, 30.0), Eigen::Vector2i(0, 1));  // the lines went round the patches
  EXPECT_EQ(r.ownership.Owner(30.0, 1.75), Eigen::Vector2i(1, 0));
  // The other boundaries' lines stay straight.
  EXPECT_EQ(r.ownership.Owner(1.75, -30.0), Eigen::Vector2i(1, 0));
  EXPECT_EQ(r.ownership.Owner(1.75, 94.0), Eigen::Vector2i(1, 2));
  EXPECT_EQ(r.ownership.Owner(94.0, 1.75), Eigen::Vector2i(2, 1));
  EXPECT_EQ(r.ownership.Owner(-30.0, 1.75), Eigen::Vector2i(0, 1));
  EXPECT_EQ(r.ownership.Owner(65.75, 30.0), Eigen::Vector2i(2, 1));
}

TEST(SeamLines, NothingGoesToAMissingTileNearACorner) {
  // Tile (1, 1) did not finish. Tiles (1, 0) and (0, 1) raised patches by
  // the corner that reach 1 m into (0, 0)'s core, so both lines beside
  // (0, 0) bend into its core there (to x, y = -1.5). A point at (-0.5,
  // -0.5) then crosses both lines; its row must come from the line of the
  // column it went to ((1, 0) | (1, 1): straight), not toward (1, 1).
  std::vector<TileCloud> tiles = Reconstruct(SurfaceCloud(), 0.0);
  tiles.pop_back();
  for (Eigen::Vector3f& p : tiles[1].cloud.means)
    if (p.x() >= -1 && p.x() < 3.5 && p.y() >= -4 && p.y() < 0) p.z() += 4.0f;
  for (Eigen::Vector3f& p : tiles[2].cloud.means)
    if (p.y() >= -1 && p.y() < 3.5 && p.x() >= -4 && p.x() < 0) p.z() += 4.0f;
  const TileOwnership own = PlanSeamLinesOnCentres(SeamLineOptions{}, tiles);
  EXPECT_EQ(own.lines(), 2u);
  EXPECT_EQ(own.Owner(-0.75, -2.0), Eigen::Vector2i(1, 0));  // the vertical line bent into (0, 0)
  EXPECT_EQ(own.Owner(-2.0, -0.75), Eigen::Vector2i(0, 1));  // and the horizontal one
  EXPECT_EQ(own.Owner(-0.5, -0.5), Eigen::Vector2i(1, 0));
  for (double y = -6; y < 6; y += 0.1) {
    for (double x = -6; x < 6; x += 0.1) {
      if (TestGrid().Owner(x, y) == Eigen::Vector2i(1, 1)) continue;
      ASSERT_NE(own.Owner(x, y), Eigen::Vector2i(1, 1)) << x << " " << y;
    }
  }
}

TEST(SeamLines, OptionsNameTheBadField) {
  auto field_of = [](auto mutate) {
    StitchOptions o;
    mutate(o.seam_lines);
    try {
      o.Check();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(field_of([](SeamLineOptions& s) { s.band_fraction = 1.5; }).find("seam_lines.band_fraction"), std::string::npos);
  EXPECT_NE(field_of([](SeamLineOptions& s) { s.cell_m = 0; }).find("seam_lines.cell_m"), std::string::npos);
  EXPECT_NE(field_of([](SeamLineOptions& s) { s.centre_pull_m = 0; }).find("seam_lines.centre_pull_m"), std::string::npos);
  EXPECT_EQ(field_of([](SeamLineOptions&) {}), "no error");
}

}  // namespace
}  // namespace skyfall
