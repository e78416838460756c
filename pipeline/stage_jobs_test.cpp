#include "pipeline/stage_jobs.h"

#include <gtest/gtest.h>

namespace skyfall {
namespace {

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
