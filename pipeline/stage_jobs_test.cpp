#include "pipeline/stage_jobs.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include "core/ground_cell.h"
#include "core/pinhole.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

// An SfM folder whose cameras.json holds one nadir view 617 km above the
// frame origin (WorldView-3's orbit) whose pixel spans `gsd_m` there.
std::string SfmAtGsd(const std::string& name, double gsd_m) {
  const fs::path dir = testing::ScratchDir("train_downscale_" + name);
  const double f_px = 617000.0 / gsd_m;
  std::ofstream file(dir / "cameras.json");
  file.precision(17);  // the focal length exactly, so that the GSD read back is exact up to rounding
  file << R"({"images": [{"name": "a", "K": [[)" << f_px << ", 0, 50], [0, " << f_px << R"(, 40], [0, 0, 1]], "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                                         "t": [0, 0, 617000], "width_px": 100, "height_px": 80}]})";
  return dir.string();
}

TEST(TrainDownscale, HalvesSubMetreImageryAndKeepsCoarserAtItsOwnResolution) {
  EXPECT_EQ(ResolveTrainDownscale(0, SfmAtGsd("wv3", 0.31)).factor, 2);
  EXPECT_EQ(ResolveTrainDownscale(0, SfmAtGsd("pleiades", 0.5)).factor, 2);
  EXPECT_EQ(ResolveTrainDownscale(0, SfmAtGsd("under", 0.999)).factor, 2);
  EXPECT_EQ(ResolveTrainDownscale(0, SfmAtGsd("over", 1.001)).factor, 1);
  const TrainDownscale zy3 = ResolveTrainDownscale(0, SfmAtGsd("zy3", 2.1));
  EXPECT_EQ(zy3.factor, 1);
  EXPECT_NEAR(zy3.finest_gsd_m, 2.1, 1e-9);  // depth over focal length: exact up to rounding
  EXPECT_NE(zy3.why.find("2.10 m"), std::string::npos) << zy3.why;
  // Asked for, the factor is kept whatever the imagery, and cameras.json is not read.
  const TrainDownscale asked = ResolveTrainDownscale(3, "/nonexistent/sfm");
  EXPECT_EQ(asked.factor, 3);
  EXPECT_NE(asked.why.find("train.downscale 3"), std::string::npos) << asked.why;
  // No usable GSD: the sub-metre setting.
  EXPECT_EQ(TrainDownscaleForGsdM(std::numeric_limits<double>::quiet_NaN()), 2);
  EXPECT_EQ(TrainDownscaleForGsdM(std::numeric_limits<double>::infinity()), 2);
  EXPECT_EQ(TrainDownscaleForGsdM(0.0), 2);
}

// The automatic spacing of a dense start: two dense cells, at least 1 m,
// so every sub-metre sensor (0.5 m cells) keeps the 1 m it was measured
// with and a 2.1 m sensor (1 m cells) starts one Gaussian per pixel.
TEST(InitSpacing, TwoDenseCellsAtLeastAMetreUnlessAsked) {
  TrainStageOptions stage;  // init_spacing_m 0: automatic
  DenseCells cells;
  for (const auto& [cell_m, expected_m] : {std::pair{0.5, 1.0}, {1.0, 2.0}, {1.5, 3.0}, {0.25, 1.0}}) {
    cells.cell_m = cell_m;
    const InitSpacing s = InitSpacingM(stage, cells);
    EXPECT_DOUBLE_EQ(s.value_m, expected_m) << cell_m;
    EXPECT_NE(s.why.find("automatic"), std::string::npos) << s.why;
  }
  // A grid without a usable cell: the sub-metre setting.
  for (double bad : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()})
    EXPECT_DOUBLE_EQ(InitSpacingForDenseCellM(bad), kMinInitSpacingM) << bad;
  // Asked for, the spacing is kept whatever the grid.
  stage.init_spacing_m = 0.75;
  cells.cell_m = 1.0;
  const InitSpacing asked = InitSpacingM(stage, cells);
  EXPECT_DOUBLE_EQ(asked.value_m, 0.75);
  EXPECT_EQ(asked.why, "train.init_spacing_m");
}

// Dense cells of `cell_m` on an n x n grid: ground at 0 m, a roof of
// `roof_m` over the columns i >= n / 2, and one filled ground cell at (1, 1).
DenseCells RoofBesideGround(int n, double cell_m, float roof_m) {
  DenseCells cells;
  cells.cell_m = cell_m;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      // An origin that is not a multiple of the cell: the cells' own corner is found.
      cells.points.emplace_back(static_cast<float>(101.3 + i * cell_m), static_cast<float>(-7.1 + j * cell_m),
                                i >= n / 2 ? roof_m : 0.0f);
      cells.colours.emplace_back(0.5f, 0.5f, 0.5f);
      cells.filled.push_back(i == 1 && j == 1);
    }
  return cells;
}

TEST(AnchorCellWeights, CellsWithinReachOfAStepOnEitherSideWeighLess) {
  const int n = 16;
  const DenseCells cells = RoofBesideGround(n, 0.5, 10.0f);
  AnchorWeightOptions o;
  o.step_weight = 0.2;
  o.step_reach_m = 1.0;  // 2 cells
  const std::vector<float> w = AnchorCellWeights(cells, o);
  ASSERT_EQ(w.size(), cells.points.size());
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      // The step lies between columns 7 and 8: columns 6..9 have both sides within 2 cells.
      const bool beside = i >= n / 2 - 2 && i <= n / 2 + 1;
      EXPECT_FLOAT_EQ(w[static_cast<std::size_t>(j) * n + i], beside ? 0.2f : 1.0f) << "cell " << i << ", " << j;
    }
}

TEST(CellsNearSteps, MarksBothSidesOfAStepWithinReachAndNothingWithoutReach) {
  const int n = 16;
  const DenseCells cells = RoofBesideGround(n, 0.5, 10.0f);
  const std::vector<std::uint8_t> near = CellsNearSteps(cells, 1.0, 2.0);  // 2 cells
  ASSERT_EQ(near.size(), cells.points.size());
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      EXPECT_EQ(near[static_cast<std::size_t>(j) * n + i], i >= n / 2 - 2 && i <= n / 2 + 1) << i << ", " << j;
  for (std::uint8_t v : CellsNearSteps(cells, 0.0, 2.0)) EXPECT_EQ(v, 0);    // no reach: none
  for (std::uint8_t v : CellsNearSteps(cells, 1.0, 10.5)) EXPECT_EQ(v, 0);   // the step is not higher than this
}

TEST(AnchorCellWeights, SlopesBelowTheStepHeightAndUnitWeightsLeaveNoWeights) {
  const DenseCells low = RoofBesideGround(12, 0.5, 1.5f);  // a kerb, not a wall
  AnchorWeightOptions o;
  o.step_weight = 0.2;
  const std::vector<float> w = AnchorCellWeights(low, o);
  for (float x : w) EXPECT_FLOAT_EQ(x, 1.0f);
  // Every weight 1: no weights at all (SurfaceDepthPrior's unweighted path).
  AnchorWeightOptions unit;
  unit.filled_weight = 1.0;
  unit.step_weight = 1.0;
  EXPECT_TRUE(AnchorCellWeights(RoofBesideGround(12, 0.5, 10.0f), unit).empty());
}

TEST(AnchorCellWeights, AFilledCellBesideAStepTakesTheLowerOfItsTwoWeights) {
  const int n = 6;  // roof from column 3: the filled cell (1, 1) is 2 cells from it
  const DenseCells cells = RoofBesideGround(n, 0.5, 10.0f);
  AnchorWeightOptions o;
  o.filled_weight = 0.1;
  o.step_weight = 0.3;
  const std::vector<float> w = AnchorCellWeights(cells, o);
  EXPECT_FLOAT_EQ(w[1 * n + 1], 0.1f);  // filled and beside the step
  EXPECT_FLOAT_EQ(w[2 * n + 1], 0.3f);  // only beside the step
  EXPECT_FLOAT_EQ(w[2 * n + 0], 1.0f);  // 3 cells away, measured
  o.step_weight = 1.0;                  // steps ignored: only the filled cell
  const std::vector<float> filled_only = AnchorCellWeights(cells, o);
  EXPECT_FLOAT_EQ(filled_only[1 * n + 1], 0.1f);
  EXPECT_FLOAT_EQ(filled_only[2 * n + 1], 1.0f);
}

}  // namespace
}  // namespace skyfall
