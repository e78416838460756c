// The dense stage's quality layers (how each cell got its height, how many
// views see it, the terrain model under it) and their round trip through
// dense.ply.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "core/atomic_file.h"
#include "dense/dense.h"
#include "dense/dense_cells.h"
#include "dense/dense_test_scene.h"

namespace skyfall {
namespace {

constexpr double kStreetHalfM = testing::StreetScene::kStreetHalfM;

DenseResult StreetScene() {
  NullProgress progress;
  const testing::StreetScene scene = testing::StreetBetweenTwoBuildings();
  return RunDenseHeights(DenseOptions{}, scene.views, scene.pairs, scene.points, progress);
}

bool OnRoof(double x, double y) { return std::abs(y) < 11 && std::abs(x) > kStreetHalfM + 1 && std::abs(x) < kStreetHalfM + 11; }

TEST(DenseQuality, EveryCellSaysHowItGotItsHeightAndWhoSeesIt) {
  const DenseResult r = StreetScene();
  ASSERT_EQ(r.report.status, StageStatus::kOk) << r.report.message;
  const HeightGrid& g = r.grid;
  ASSERT_EQ(g.fill_rule.size(), g.height_m.size());
  ASSERT_EQ(g.views.size(), g.height_m.size());
  ASSERT_EQ(g.terrain_m.size(), g.height_m.size());
  double street_views = 0, roof_views = 0;
  int street = 0, roof = 0, matched = 0, matched_seen_twice = 0;
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = g.Index(i, j);
      if (!std::isfinite(g.height_m[k])) continue;
      // A rule says filled exactly where the cell is flagged filled.
      EXPECT_EQ(g.fill_rule[k] != FillRule::kMatched, g.filled[k] != 0) << i << "," << j;
      EXPECT_LE(static_cast<int>(g.fill_rule[k]), static_cast<int>(FillRule::kSideByViews));
      EXPECT_LE(g.views[k], 6);
      if (g.fill_rule[k] == FillRule::kMatched) {
        ++matched;
        matched_seen_twice += g.views[k] >= 2;
      }
      const double x = g.x0_m + i * g.cell_m, y = g.y0_m + j * g.cell_m;
      if (std::abs(x) < kStreetHalfM - 0.5 && std::abs(y) < 8) {
        ++street;
        street_views += g.views[k];
      }
      if (OnRoof(x, y)) {
        ++roof;
        roof_views += g.views[k];
        // The terrain model is the bare earth: under a roof it is the ground (0 m).
        if (std::isfinite(g.terrain_m[k])) EXPECT_NEAR(g.terrain_m[k], 0.0f, 1.0f) << x << "," << y;
      }
    }
  ASSERT_GT(matched, 0);
  ASSERT_GT(street, 0);
  ASSERT_GT(roof, 0);
  // A height a pair matched was seen by that pair (a few cells at walls
  // are hidden on the final surface by a neighbour's height).
  EXPECT_GE(static_cast<double>(matched_seen_twice) / matched, 0.95);
  // The walls hide the street's floor from the views across it (12-22 deg
  // off nadir, a 20 m wall hides 4-8 m): fewer views see it than a roof.
  EXPECT_LT(street_views / street, roof_views / roof - 1.0);
}

TEST(DenseQuality, TheLayersRoundTripThroughDensePly) {
  const DenseResult r = StreetScene();
  ASSERT_EQ(r.report.status, StageStatus::kOk) << r.report.message;
  const HeightGrid& g = r.grid;
  const std::string path = (std::filesystem::temp_directory_path() / "dense_quality_round_trip.ply").string();
  WriteFileAtomic(path, DenseCellsPly(g));
  const DenseCells cells = ReadDenseCells(path);
  ASSERT_EQ(cells.fill_rule.size(), cells.points.size());
  ASSERT_EQ(cells.views.size(), cells.points.size());
  ASSERT_EQ(cells.terrain_m.size(), cells.points.size());
  ASSERT_EQ(cells.cost.size(), cells.points.size());
  std::size_t n = 0;
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = g.Index(i, j);
      if (!std::isfinite(g.height_m[k])) continue;
      ASSERT_LT(n, cells.points.size());
      EXPECT_EQ(cells.fill_rule[n], g.fill_rule[k]);
      EXPECT_EQ(cells.views[n], g.views[k]);
      if (std::isfinite(g.terrain_m[k])) {
        EXPECT_NEAR(cells.terrain_m[n], g.terrain_m[k], 0.0005f);  // written to the millimetre
      } else {
        EXPECT_TRUE(std::isnan(cells.terrain_m[n]));
      }
      ++n;
    }
  EXPECT_EQ(n, cells.points.size());
}

// A dense.ply of an earlier version (no rule, views or terrain) still reads;
// its quality layers are empty.
TEST(DenseQuality, AnOlderDensePlyReadsWithoutItsLayers) {
  const std::string path = (std::filesystem::temp_directory_path() / "dense_quality_older.ply").string();
  WriteFileAtomic(path,
                  "ply\nformat ascii 1.0\ncomment skyfall dense heights, ENU metres, one point per 0.500000 m cell\n"
                  "element vertex 2\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\n"
                  "property uchar green\nproperty uchar blue\nproperty float matching_cost\nproperty uchar filled\n"
                  "end_header\n0.000 0.000 1.000 10 20 30 0.1000 0\n0.500 0.000 2.000 10 20 30 0.2000 1\n");
  const DenseCells cells = ReadDenseCells(path);
  ASSERT_EQ(cells.points.size(), 2u);
  EXPECT_EQ(cells.filled[1], 1);
  EXPECT_TRUE(cells.fill_rule.empty());
  EXPECT_TRUE(cells.terrain_m.empty());
  EXPECT_EQ(cells.cost.size(), 2u);
}

}  // namespace
}  // namespace skyfall
