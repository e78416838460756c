#include "dense/hole_fill.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "core/error.h"

namespace skyfall {
namespace {

// The basic rules on grids of 0.5 m cells: 5 m first reach, 20 m largest,
// 30 m ground radius, the roof-rim rule; the product's further rules off
// (each test turns on the ones it is about).
HoleFillGrid FillOptions() {
  HoleFillGrid o;
  o.radius_cells = 10;
  o.max_reach_cells = 40;
  o.ground_radius_cells = 60;
  o.ground_tolerance_m = 1.0f;
  o.ground_max_rise_m = 0.0f;
  o.terrain_block_cells = 8;
  o.roof_rim_fraction = 0.9f;
  o.roof_rim_min_m = 2.0f;
  o.roof_rim_occluded = false;
  o.roof_enclosed = false;
  o.far_raised_takes_ground = false;
  o.seen_ground_takes_terrain = false;
  return o;
}

// One set of defaults: the grid form of the options the product runs holds
// every rule it runs, at the 0.5 m cell the distances above.
TEST(HoleFill, TheProductsOptionsOnAGridAreTheProductsRules) {
  const HoleFillGrid g = HoleFillOptions{}.OnGrid(0.5);
  EXPECT_EQ(g.radius_cells, 10);
  EXPECT_EQ(g.max_reach_cells, 40);
  EXPECT_EQ(g.ground_radius_cells, 60);
  EXPECT_EQ(g.ground_max_rise_m, 10.0f);
  EXPECT_TRUE(g.roof_rim_occluded && g.roof_enclosed && g.far_raised_takes_ground && g.seen_ground_takes_terrain);
  EXPECT_EQ(HoleFillOptions{}.OnGrid(2.0).radius_cells, 3);  // 5 m on a 2 m grid: 2.5 cells, rounded away
  HoleFillOptions tiny;
  tiny.radius_m = 0.1;
  EXPECT_EQ(tiny.OnGrid(0.5).radius_cells, 1);  // never less than a cell
  // A grid form made by hand with nothing set is refused, not run with
  // rules of its own.
  std::vector<float> h(16, 1.0f);
  h[5] = NAN;
  EXPECT_THROW(FillHoles(h, 4, 4, HoleFillGrid{}, GroundModel{}, nullptr), Error);
}

std::vector<std::uint8_t> Fill(std::vector<float>& h, int nx, int ny, const HoleFillGrid& o,
                               const std::vector<std::uint8_t>* occluded = nullptr) {
  return FillHoles(h, nx, ny, o, GroundModelOf(h, nx, ny, o), occluded);
}

TEST(MinFilter, TheSquaresLowestFiniteValueCutOrMovedAtTheEdges) {
  const int nx = 7, ny = 5;
  std::vector<float> h(nx * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) h[j * nx + i] = static_cast<float>(10 * j + i);  // lowest at the top-left
  h[2 * nx + 3] = NAN;
  h[4 * nx + 6] = -5.0f;
  // Against a brute-force minimum over the square, cut at the grid's edges.
  const std::vector<float> clipped = MinFilter(h, nx, ny, 1, WindowEdge::kClip);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      float m = INFINITY;
      for (int b = std::max(0, j - 1); b <= std::min(ny - 1, j + 1); ++b)
        for (int a = std::max(0, i - 1); a <= std::min(nx - 1, i + 1); ++a)
          if (std::isfinite(h[b * nx + a])) m = std::min(m, h[b * nx + a]);
      EXPECT_FLOAT_EQ(clipped[j * nx + i], m) << i << ", " << j;
    }
  // Moved inside whole, a corner's square is the 3 x 3 block at the corner.
  const std::vector<float> shifted = MinFilter(h, nx, ny, 1, WindowEdge::kShift);
  EXPECT_FLOAT_EQ(shifted[0], 0.0f);
  EXPECT_FLOAT_EQ(shifted[4 * nx + 6], -5.0f);
  EXPECT_FLOAT_EQ(shifted[0 * nx + 6], 4.0f);  // columns 4-6, rows 0-2
  // A square of NaN only stays NaN.
  EXPECT_TRUE(std::isnan(MinFilter(std::vector<float>(9, NAN), 3, 3, 1, WindowEdge::kClip)[4]));
}

TEST(HoleFill, HolesBesideAWallAreGroundAndHolesInARoofTakeTheRoof) {
  // Flat ground (0 m) with a 10 m roof in the west; a 3-cell hole between
  // them (ground hidden by the wall: roof on one side, ground on the other)
  // must take the ground, and a one-cell hole inside the roof, whose reach
  // holds only roof, the roof. Nothing measured may change.
  const int nx = 60, ny = 8;
  const float nan = std::nanf("");
  std::vector<float> h(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) h[j * nx + i] = i < 10 ? 10.0f : i < 13 ? nan : 0.0f;
  h[3 * nx + 4] = nan;
  const std::vector<float> before = h;
  HoleFillGrid o = FillOptions();
  o.radius_cells = 3;
  const std::vector<std::uint8_t> filled = Fill(h, nx, ny, o);
  // Tolerance: float rounding of the terrain's plane fits over ~10 m.
  constexpr float kTol = 1e-4f;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * nx + i;
      const bool wall_hole = i >= 10 && i < 13, roof_hole = i == 4 && j == 3;
      EXPECT_EQ(filled[k], wall_hole || roof_hole ? 1 : 0) << i << "," << j;
      if (wall_hole) EXPECT_NEAR(h[k], 0.0f, kTol) << i << "," << j;
      else if (roof_hole) EXPECT_NEAR(h[k], 10.0f, kTol);
      else EXPECT_EQ(h[k], before[k]);
    }
}

// A 10 m roof (columns 0-39) on flat ground with an unmatched patch 2-6
// cells inside its east edge: the ground beyond the edge is within the
// first reach, but every measured cell around the patch is roof.
std::vector<float> RoofWithAHoleNearItsEdge(int nx, int ny) {
  std::vector<float> h(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const bool hole = i >= 34 && i <= 37 && j >= 4 && j <= 9;
      h[static_cast<std::size_t>(j) * nx + i] = hole ? std::nanf("") : i < 40 ? 10.0f : 0.0f;
    }
  return h;
}

TEST(HoleFill, AHoleRingedByRoofTakesTheRoofThoughGroundIsInReach) {
  const int nx = 80, ny = 14;
  std::vector<float> h = RoofWithAHoleNearItsEdge(nx, ny);
  const std::vector<std::uint8_t> filled = Fill(h, nx, ny, FillOptions());
  for (int j = 4; j <= 9; ++j)
    for (int i = 34; i <= 37; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * nx + i;
      EXPECT_EQ(filled[k], 1);
      EXPECT_NEAR(h[k], 10.0f, 1e-4f) << i << "," << j;  // float rounding of the ground's plane fit
    }
  // Off, the patch takes the ground beyond the edge: the lowest in reach.
  std::vector<float> plain = RoofWithAHoleNearItsEdge(nx, ny);
  HoleFillGrid off = FillOptions();
  off.roof_rim_fraction = 0;
  Fill(plain, nx, ny, off);
  EXPECT_NEAR(plain[static_cast<std::size_t>(6) * nx + 36], 0.0f, 1e-4f);
  // A rim share outside [0, 1] is refused, naming the option.
  HoleFillGrid bad = FillOptions();
  bad.roof_rim_fraction = 1.5f;
  try {
    Fill(plain, nx, ny, bad);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("fill_roof_rim_fraction"), std::string::npos) << e.what();
  }
}

// A 10 m roof over columns 70-129 on flat ground (0 m), with a patch no
// pair measured in its middle (columns 90-115, rows 5-34: cells up to 13
// from the roof, beyond the first reach of 10) and a 3-cell strip beside its
// east wall. The ground under both is hidden from every pair (`occluded`): the
// patch's by the roof around it, the strip's by the wall.
struct RoofWithAnOccludedHole {
  static constexpr int nx = 200, ny = 40;
  std::vector<float> h;
  std::vector<std::uint8_t> occluded;
  static bool Patch(int i, int j) { return i >= 90 && i <= 115 && j >= 5 && j <= 34; }
  static bool Strip(int i) { return i >= 130 && i <= 132; }
  RoofWithAnOccludedHole() : h(static_cast<std::size_t>(nx) * ny), occluded(h.size(), 0) {
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const std::size_t k = static_cast<std::size_t>(j) * nx + i;
        const bool hole = Patch(i, j) || Strip(i);
        h[k] = hole ? std::nanf("") : i >= 70 && i < 130 ? 10.0f : 0.0f;
        occluded[k] = hole ? 1 : 0;
      }
  }
};

TEST(HoleFill, AnOccludedHoleRingedByRoofTakesTheRoofAndAStripBesideAWallTheGround) {
  using Scene = RoofWithAnOccludedHole;
  HoleFillGrid o = FillOptions();
  o.roof_rim_occluded = true;
  Scene on;
  const std::vector<std::uint8_t> filled = Fill(on.h, Scene::nx, Scene::ny, o, &on.occluded);
  // Tolerance: float rounding of the terrain's plane fits over ~50 m.
  constexpr float kTol = 1e-4f;
  for (int j = 0; j < Scene::ny; ++j)
    for (int i = 0; i < Scene::nx; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * Scene::nx + i;
      if (Scene::Patch(i, j)) {
        EXPECT_EQ(filled[k], 1);
        EXPECT_NEAR(on.h[k], 10.0f, kTol) << i << "," << j;  // the deepest cells too, though beyond the first reach
      } else if (Scene::Strip(i)) {
        EXPECT_NEAR(on.h[k], 0.0f, kTol) << i << "," << j;  // half its rim is ground: not a roof's hole
      }
    }
  // Off, occluded cells are ground whatever surrounds them: the patch takes
  // the terrain.
  Scene off;
  o.roof_rim_occluded = false;
  Fill(off.h, Scene::nx, Scene::ny, o, &off.occluded);
  EXPECT_NEAR(off.h[static_cast<std::size_t>(20) * Scene::nx + 102], 0.0f, kTol);
  EXPECT_NEAR(off.h[static_cast<std::size_t>(20) * Scene::nx + 131], 0.0f, kTol);
}

TEST(HoleFill, AHoleEnclosedByRoofTakesTheRoofThoughItsPieceReachesHiddenGround) {
  // A 30 m roof at 20 m (columns 20-79, rows 10-69) on measured ground at 0,
  // a hole in it (columns 40-69, rows 25-54) and a gap through its east
  // edge (rows 38-41) into a strip of ground hidden behind a tower further
  // east (columns 80-119; the tower, 100 m, from column 120). All hole cells
  // are occluded. Hole, gap and strip are one piece, whose rim is about 75%
  // raised: not a roof's hole by its rim.
  const int nx = 140, ny = 80;
  auto roof = [](int i, int j) { return i >= 20 && i <= 79 && j >= 10 && j <= 69; };
  auto hole = [](int i, int j) { return i >= 40 && i <= 69 && j >= 25 && j <= 54; };
  auto gap = [](int i, int j) { return i >= 70 && i <= 79 && j >= 38 && j <= 41; };
  auto strip = [](int i, int j) { return i >= 80 && i <= 119 && j >= 10 && j <= 69; };
  std::vector<float> scene(static_cast<std::size_t>(nx) * ny);
  std::vector<std::uint8_t> occluded(scene.size(), 0);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * nx + i;
      const bool unmatched = hole(i, j) || gap(i, j) || strip(i, j);
      scene[k] = unmatched ? std::nanf("") : i >= 120 ? 100.0f : roof(i, j) ? 20.0f : 0.0f;
      occluded[k] = unmatched ? 1 : 0;
    }
  HoleFillGrid o = FillOptions();
  o.roof_rim_occluded = true;
  std::vector<float> on = scene, off = scene;
  o.roof_enclosed = true;
  Fill(on, nx, ny, o, &occluded);
  o.roof_enclosed = false;
  Fill(off, nx, ny, o, &occluded);
  // Tolerance: float rounding of the terrain's plane fit over ~70 m.
  constexpr float kTol = 1e-3f;
  auto at = [&](const std::vector<float>& h, int i, int j) { return h[static_cast<std::size_t>(j) * nx + i]; };
  int roof_cells = 0;
  for (int j = 25; j <= 54; ++j)
    for (int i = 40; i <= 69; ++i) {
      EXPECT_NEAR(at(off, i, j), 0.0f, kTol) << i << "," << j;  // by the piece's rim: the terrain
      // Rows in line with the gap look east through it and the hidden strip,
      // and meet the tower only beyond the reach (40 cells): not enclosed.
      if (j >= 38 && j <= 41) continue;
      EXPECT_NEAR(at(on, i, j), 20.0f, kTol) << i << "," << j;
      ++roof_cells;
    }
  EXPECT_EQ(roof_cells, 30 * 26);
  // The hidden strip's rays meet the ground north and south: it stays ground.
  for (int j = 10; j <= 69; j += 7)
    for (int i = 80; i <= 119; i += 6) EXPECT_NEAR(at(on, i, j), 0.0f, kTol) << i << "," << j;
}

TEST(HoleFill, AStreetFarFromItsMeasuredGroundTakesTheGroundNotTheRoofsBesideIt) {
  // Two 40 m roofs (columns 0-19 and 61-79) and the street between them,
  // which no pair matched (rows 0-54); its ground is measured only from row
  // 55 on. The views see the street along its length (nothing occluded).
  // Its rim is 71% roof, so it is no roof's hole; its middle has nothing
  // within the first reach (10 cells), and the first thing a wider reach
  // finds is a roof.
  const int nx = 80, ny = 80;
  auto street = [](int i, int j) { return i >= 20 && i <= 60 && j < 55; };
  std::vector<float> scene(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      scene[static_cast<std::size_t>(j) * nx + i] = street(i, j) ? std::nanf("") : j < 55 ? 40.0f : 0.0f;
  HoleFillGrid o = FillOptions();
  o.far_raised_takes_ground = true;
  std::vector<float> on = scene, off = scene;
  Fill(on, nx, ny, o);
  o.far_raised_takes_ground = false;
  Fill(off, nx, ny, o);
  // Tolerance: float rounding of the ground's plane fit over ~40 m.
  constexpr float kTol = 1e-3f;
  auto at = [&](const std::vector<float>& h, int i, int j) { return h[static_cast<std::size_t>(j) * nx + i]; };
  for (int j = 0; j < 15; ++j)  // beyond reach 40 of the measured ground
    for (int i = 31; i <= 49; ++i) {  // more than 10 cells from either roof
      EXPECT_NEAR(at(on, i, j), 0.0f, kTol) << i << "," << j;
      EXPECT_NEAR(at(off, i, j), 40.0f, kTol) << i << "," << j;  // off: the lowest in reach, a roof
    }
  // Within the first reach of a roof the roof is taken either way (what a
  // window-wide unmatched band beside a roof most often is).
  for (int j = 0; j < 15; ++j) {
    EXPECT_NEAR(at(on, 22, j), 40.0f, kTol) << j;
    EXPECT_NEAR(at(on, 58, j), 40.0f, kTol) << j;
  }
}

TEST(HoleFill, ASeenHoleOnAHillsideTakesTheGroundOnTheSlope) {
  // A 30% slope rising east (0.15 m per 0.5 m cell) measured only east of
  // column 80; the views see the western part but no pair matched it. The
  // lowest height in reach of each hole cell is ground, so the hole is
  // ground: with seen_ground_takes_terrain it takes the terrain model, the
  // slope carried on; without, the plain opening there, which is the lowest
  // ground within the ground radius but the highest such low within it
  // again: the ground at column 80, metres above the hole's own.
  const int nx = 160, ny = 40;
  auto plane = [](int i) { return 0.15f * i; };
  std::vector<float> scene(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) scene[static_cast<std::size_t>(j) * nx + i] = i < 80 ? std::nanf("") : plane(i);
  HoleFillGrid o = FillOptions();
  o.seen_ground_takes_terrain = true;
  std::vector<float> on = scene, off = scene;
  const std::vector<std::uint8_t> filled = Fill(on, nx, ny, o);
  o.seen_ground_takes_terrain = false;
  Fill(off, nx, ny, o);
  // Tolerance: float rounding of the terrain's plane fits and trend over ~24 m.
  constexpr float kTol = 1e-3f;
  auto at = [&](const std::vector<float>& h, int i, int j) { return h[static_cast<std::size_t>(j) * nx + i]; };
  for (int j = 0; j < ny; j += 3)
    for (int i = 40; i < 80; ++i) {  // within the largest reach (40 cells) of the measured ground
      EXPECT_EQ(filled[static_cast<std::size_t>(j) * nx + i], 1) << i << "," << j;
      EXPECT_NEAR(at(on, i, j), plane(i), kTol) << i << "," << j;
      // Off: the ground at column 80 and beyond, at least 1 m above the slope 7 cells away.
      if (i <= 73) EXPECT_GT(at(off, i, j), plane(i) + 1.0f) << i << "," << j;
    }
  EXPECT_TRUE(std::isnan(at(on, 39, 0)));  // beyond reach: nothing to fill from
}

TEST(HoleFill, WithoutATerrainModelASeenGroundHoleKeepsTheOpeningPlusItsLowest) {
  // Flat ground with a 1 m platform 20 m wide (narrower than the opening's
  // square, so the opening there is the ground at 0 m) holding a small
  // unmatched hole, and no terrain model anywhere: seen_ground_takes_terrain
  // has nothing to take, and the hole is filled as without it, at the
  // opening plus the lowest height in reach (the platform, 1 m: within
  // roof_rim_min_m, so ground), not at the bare opening.
  const int nx = 200, ny = 60;
  constexpr float kPlatformM = 1.0f;
  std::vector<float> scene(static_cast<std::size_t>(nx) * ny, 0.0f);
  for (int j = 10; j < 50; ++j)
    for (int i = 85; i < 125; ++i)
      scene[static_cast<std::size_t>(j) * nx + i] = i >= 103 && i <= 106 && j >= 28 && j <= 32 ? std::nanf("") : kPlatformM;
  HoleFillGrid o = FillOptions();
  GroundModel model = GroundModelOf(scene, nx, ny, o);
  std::fill(model.terrain_m.begin(), model.terrain_m.end(), std::nanf(""));
  std::vector<float> on = scene, off = scene;
  o.seen_ground_takes_terrain = true;
  FillHoles(on, nx, ny, o, model);
  o.seen_ground_takes_terrain = false;
  FillHoles(off, nx, ny, o, model);
  for (int j = 28; j <= 32; ++j)
    for (int i = 103; i <= 106; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * nx + i;
      EXPECT_EQ(model.seen_hole_base_m[k], 0.0f) << i << "," << j;
      EXPECT_EQ(off[k], kPlatformM) << i << "," << j;
      EXPECT_EQ(on[k], off[k]) << i << "," << j;
    }
}

TEST(HoleFill, AnOccludedStripIsGroundOnItsSlopeUpToTheGridEdge) {
  // A 30% slope rising east (0.5 m cells: 0.15 m per cell) and a 40 m tall
  // building whose south wall hides a 20-cell strip of ground that runs to
  // the grid's south edge: within reach of most of the strip there is only
  // roof. Marked occluded (no pair sees it) it is ground and follows the
  // slope; left to the reach rule it would take the roof.
  const int nx = 160, ny = 60;
  const float nan = std::nanf("");
  auto plane = [](int i) { return 0.15f * i; };
  std::vector<float> h(static_cast<std::size_t>(nx) * ny);
  std::vector<std::uint8_t> occluded(h.size(), 0);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * nx + i;
      const bool building = i >= 40 && i < 120 && j >= 20 && j < 50;
      const bool hidden = i >= 40 && i < 120 && j < 20;
      h[k] = hidden ? nan : plane(i) + (building ? 40.0f : 0.0f);
      occluded[k] = hidden ? 1 : 0;
    }
  const std::vector<float> measured = h;
  std::vector<float> unmarked = h;
  const std::vector<std::uint8_t> filled = Fill(h, nx, ny, FillOptions(), &occluded);
  Fill(unmarked, nx, ny, FillOptions());
  // Tolerance: exact for a plane but for float rounding of ~40 m heights.
  constexpr float kTol = 1e-4f;
  int roof_without_mark = 0;
  for (int j = 0; j < 20; ++j)
    for (int i = 40; i < 120; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * nx + i;
      EXPECT_EQ(filled[k], 1);
      EXPECT_NEAR(h[k], plane(i), kTol) << i << "," << j;
      roof_without_mark += unmarked[k] > plane(i) + 20.0f ? 1 : 0;
    }
  EXPECT_GT(roof_without_mark, 20 * 40);  // what visibility buys: most of the strip
  // The ground surface keeps the plane under the building and removes it,
  // also within its radius of the uphill edge.
  const std::vector<float> ground = GroundSurface(measured, nx, ny, 60, 0.0f);
  EXPECT_NEAR(ground[35 * nx + 80], plane(80), kTol);
  EXPECT_NEAR(ground[10 * nx + 150], plane(150), kTol);
  EXPECT_THROW(GroundSurface(measured, nx, ny, 0, 0.0f), Error);
}

TEST(HoleFill, TheTerrainModelSpansWideHolesOnAPlane) {
  // A tilted plane (0.1 m and -0.05 m per cell) with a 40 x 30 cell hole and
  // a 12 m block: the terrain model is the plane everywhere, the hole and
  // the block included, where an opening would flatten across the hole.
  const int nx = 120, ny = 90;
  const float nan = std::nanf("");
  auto plane = [](int i, int j) { return 3.0f + 0.1f * i - 0.05f * j; };
  std::vector<float> h(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const bool hole = i >= 30 && i < 70 && j >= 20 && j < 50;
      const bool block = i >= 80 && i < 100 && j >= 60 && j < 80;
      h[static_cast<std::size_t>(j) * nx + i] = hole ? nan : plane(i, j) + (block ? 12.0f : 0.0f);
    }
  const GroundModel model = GroundModelOf(h, nx, ny, FillOptions());
  // Tolerance: float rounding of block plane fits and the harmonic fill's
  // convergence threshold.
  constexpr float kTol = 1e-3f;
  for (int j = 0; j < ny; j += 3)
    for (int i = 0; i < nx; i += 3)
      EXPECT_NEAR(model.terrain_m[static_cast<std::size_t>(j) * nx + i], plane(i, j), kTol) << i << "," << j;
  std::vector<float> no_ground(h.size(), nan);
  const GroundModel empty = GroundModelOf(no_ground, nx, ny, FillOptions());
  for (float t : empty.terrain_m) EXPECT_TRUE(std::isnan(t));
}

TEST(HoleFill, TheTerrainModelKeepsTheSlopeAcrossHiddenGround) {
  // Ground rising 0.1 m per cell east, measured over the western half only
  // (the eastern half hidden, say, between tall buildings): the terrain
  // model goes on up the slope instead of levelling out at the last
  // measured height.
  const int nx = 200, ny = 40;
  const float nan = std::nanf("");
  auto plane = [](int i) { return 2.0f + 0.1f * i; };
  std::vector<float> h(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) h[static_cast<std::size_t>(j) * nx + i] = i < 100 ? plane(i) : nan;
  const GroundModel model = GroundModelOf(h, nx, ny, FillOptions());
  // Tolerance: float rounding of block plane fits and the harmonic fill's
  // convergence threshold, as for the plane with a hole.
  constexpr float kTol = 1e-3f;
  for (int i = 0; i < nx; i += 7) EXPECT_NEAR(model.terrain_m[static_cast<std::size_t>(20) * nx + i], plane(i), kTol) << i;
}

// Ground of a hill (the quadratic `hill`, 0.5 m cells) or of a plane with
// ripples, measured everywhere but in the south-west quadrant, which is
// hidden: the terrain model's value there against the truth.
struct HiddenQuadrant {
  static constexpr int kSide = 160;
  template <typename Ground>
  static std::vector<float> Measured(const Ground& ground) {
    std::vector<float> h(static_cast<std::size_t>(kSide) * kSide);
    for (int j = 0; j < kSide; ++j)
      for (int i = 0; i < kSide; ++i)
        h[static_cast<std::size_t>(j) * kSide + i] = i < kSide / 2 && j < kSide / 2 ? std::nanf("") : ground(i, j);
    return h;
  }
  // The largest error of `terrain` over the hidden quadrant.
  template <typename Ground>
  static float WorstHiddenError(const std::vector<float>& terrain, const Ground& ground) {
    float worst = 0;
    for (int j = 0; j < kSide / 2; ++j)
      for (int i = 0; i < kSide / 2; ++i)
        worst = std::max(worst, std::abs(terrain[static_cast<std::size_t>(j) * kSide + i] - ground(i, j)));
    return worst;
  }
};

TEST(HoleFill, TheTerrainModelBendsWithAHillIntoHiddenGround) {
  // A hillside curving down to the south-west (40 m of relief over 80 m),
  // its downhill quadrant hidden: a plane through what is seen would put
  // the hidden corner metres too high (the slope steepens there); the
  // quadratic trend, which predicts the seen blocks better from each other,
  // follows the curve.
  auto hill = [](int i, int j) {
    const double a = (i - 160.0) / 160.0, b = (j - 160.0) / 160.0;
    return static_cast<float>(40.0 - 20.0 * (a * a + b * b));
  };
  const std::vector<float> h = HiddenQuadrant::Measured(hill);
  const GroundModel model = GroundModelOf(h, HiddenQuadrant::kSide, HiddenQuadrant::kSide, FillOptions());
  // Tolerance: a tenth of what a plane trend misses by (5.6 m). The
  // quadratic is exact, but the opening of the ground surface rounds off
  // the hill's crest, leaving fewer ground blocks near it (0.2 m).
  constexpr float kTol = 0.56f;
  EXPECT_LT(HiddenQuadrant::WorstHiddenError(model.terrain_m, hill), kTol);
}

TEST(HoleFill, TheTerrainModelKeepsAPlaneWhereTheCurvatureIsAWave) {
  // A plane with a wave of 1 m every 60 m: a quadratic fitted to the seen
  // three quadrants bends with the wave and, extrapolated, misses the
  // hidden quadrant by up to 2.4 m; the plane predicts the seen blocks from
  // each other better and misses it by up to 1.6 m, about the wave's own
  // height.
  auto wave = [](int i, int j) {
    return static_cast<float>(5.0 + 0.1 * i - 0.05 * j + std::sin(2 * M_PI * (i + 0.7 * j) / 120.0));
  };
  const std::vector<float> h = HiddenQuadrant::Measured(wave);
  const GroundModel model = GroundModelOf(h, HiddenQuadrant::kSide, HiddenQuadrant::kSide, FillOptions());
  // Tolerance: the wave's peak-to-peak height, which no trend knows beyond
  // the seen ground.
  constexpr float kTol = 2.0f;
  EXPECT_LT(HiddenQuadrant::WorstHiddenError(model.terrain_m, wave), kTol);
}

TEST(HoleFill, SquaresThatHoldOnlyRoofsGiveNoGround) {
  // Flat ground at 0 m measured west of column 120 and east of column 360;
  // between them 20 m roofs, 40 cells wide, between 10-cell streets that
  // no view matched (NaN): the ground is hidden there. Within the 60-cell
  // radius of the opening around column 240 there are only roofs, and the
  // opening takes them for ground; the opening of twice the radius reaches
  // the measured ground, and with a 10 m rise allowed the ground surface is
  // empty there and the terrain model spans it from the ground beside it.
  const int nx = 480, ny = 60;
  const float nan = std::nanf("");
  std::vector<float> h(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const bool built = i >= 120 && i < 360;
      h[static_cast<std::size_t>(j) * nx + i] = !built ? 0.0f : ((i - 120) % 50 < 40 ? 20.0f : nan);
    }
  HoleFillGrid plain = FillOptions(), rise = FillOptions();
  rise.ground_max_rise_m = 10.0f;
  const GroundModel roofs = GroundModelOf(h, nx, ny, plain);
  const GroundModel ground = GroundModelOf(h, nx, ny, rise);
  // Tolerance: float rounding of heights of 20 m and the fits' convergence.
  constexpr float kTol = 1e-3f;
  const std::size_t west = static_cast<std::size_t>(30) * nx + 20, middle = static_cast<std::size_t>(30) * nx + 240;
  EXPECT_NEAR(roofs.ground_m[west], 0.0f, kTol);
  EXPECT_NEAR(ground.ground_m[west], 0.0f, kTol);
  EXPECT_NEAR(roofs.ground_m[middle], 20.0f, kTol);
  EXPECT_TRUE(std::isnan(ground.ground_m[middle]));
  EXPECT_NEAR(roofs.terrain_m[middle], 20.0f, kTol);
  EXPECT_NEAR(ground.terrain_m[middle], 0.0f, kTol);
  EXPECT_THROW(GroundSurface(h, nx, ny, 60, -1.0f), Error);
}

TEST(HoleFill, HolesOutOfReachStayEmptyAndBadInputNamesTheProblem) {
  // One row of 0.5 m cells: ground at both ends, 30 empty cells between.
  // With a reach of 10 cells the cells within 10 of an end are filled (as
  // ground), the middle stays empty; an all-empty grid stays empty.
  const float nan = std::nanf("");
  const int nx = 34;
  std::vector<float> h(nx, nan);
  h[0] = h[1] = 2.0f;
  h[nx - 2] = h[nx - 1] = 2.0f;
  HoleFillGrid options = FillOptions();
  options.radius_cells = 5;
  options.max_reach_cells = 10;
  const std::vector<std::uint8_t> filled = Fill(h, nx, 1, options);
  for (int i = 2; i < nx - 2; ++i) {
    const bool reachable = i <= 11 || i >= nx - 12;
    EXPECT_EQ(filled[i], reachable ? 1 : 0) << i;
    if (reachable) EXPECT_NEAR(h[i], 2.0f, 1e-5f) << i;
    else EXPECT_TRUE(std::isnan(h[i])) << i;
  }
  // Occluded ground obeys the same reach, although the terrain spans the grid.
  std::vector<float> g(nx, nan);
  g[0] = g[1] = 2.0f;
  g[nx - 2] = g[nx - 1] = 2.0f;
  const std::vector<std::uint8_t> all_occluded(nx, 1);
  const std::vector<std::uint8_t> filled_ground = Fill(g, nx, 1, options, &all_occluded);
  for (int i = 2; i < nx - 2; ++i) {
    const bool reachable = i <= 11 || i >= nx - 12;
    EXPECT_EQ(filled_ground[i], reachable ? 1 : 0) << i;
    EXPECT_EQ(std::isnan(g[i]), !reachable) << i;
  }
  std::vector<float> empty(6, nan);
  Fill(empty, 3, 2, FillOptions());
  for (float x : empty) EXPECT_TRUE(std::isnan(x));
  EXPECT_THROW(Fill(empty, 4, 2, FillOptions()), Error);
  options = FillOptions();
  options.ground_radius_cells = 0;
  EXPECT_THROW(Fill(empty, 3, 2, options), Error);
  options = FillOptions();
  options.max_reach_cells = 5;  // below the first reach
  EXPECT_THROW(Fill(empty, 3, 2, options), Error);
  const std::vector<std::uint8_t> wrong_mask(5, 0);
  std::vector<float> grid(6, 1.0f);
  EXPECT_THROW(FillHoles(grid, 3, 2, FillOptions(), GroundModelOf(grid, 3, 2, FillOptions()), &wrong_mask), Error);
}

TEST(FloatingPatch, SmallPatchesHighAboveTheTerrainGoAndRoofFragmentsStay) {
  // Terrain at 0 m; on a 60 x 40 grid: a 3 x 3 patch matched 30 m up in the
  // air (goes), a 3 x 3 patch 15 m up (below the 20 m rise: stays), a
  // 12 x 12 roof at 30 m (too large: stays), a ramp of 30 cells rising
  // 0.9 m per cell from 0 to 26 m (not wholly above the rise: stays), and
  // measured ground.
  const int nx = 60, ny = 40;
  const float nan = std::nanf("");
  std::vector<float> h(static_cast<std::size_t>(nx) * ny, nan);
  const std::vector<float> terrain(h.size(), 0.0f);
  auto fill = [&](int i0, int j0, int side, float z) {
    for (int j = j0; j < j0 + side; ++j)
      for (int i = i0; i < i0 + side; ++i) h[static_cast<std::size_t>(j) * nx + i] = z;
  };
  auto at = [&](int i, int j) { return h[static_cast<std::size_t>(j) * nx + i]; };
  fill(2, 2, 3, 30.0f);
  fill(10, 2, 3, 15.0f);
  fill(20, 2, 12, 30.0f);
  for (int i = 0; i < 30; ++i) h[static_cast<std::size_t>(16) * nx + i] = 0.9f * static_cast<float>(i);
  fill(2, 20, 15, 0.0f);
  FloatingPatchOptions o;
  o.max_cells = 100;
  std::vector<float> off = h;
  EXPECT_EQ(RemoveFloatingPatches(off, nx, ny, terrain, FloatingPatchOptions{}), 0u);  // max_cells 0: off
  EXPECT_EQ(RemoveFloatingPatches(h, nx, ny, terrain, o), 9u);
  EXPECT_TRUE(std::isnan(at(3, 3)));
  EXPECT_EQ(at(11, 3), 15.0f);
  EXPECT_EQ(at(25, 5), 30.0f);
  EXPECT_EQ(at(29, 16), 0.9f * 29.0f);
  EXPECT_EQ(at(5, 25), 0.0f);
  // Without a terrain there is nothing to float above.
  std::vector<float> again = off;
  EXPECT_EQ(RemoveFloatingPatches(again, nx, ny, std::vector<float>(h.size(), nan), o), 0u);
  o.max_cells = -1;
  EXPECT_THROW(RemoveFloatingPatches(again, nx, ny, terrain, o), Error);
  EXPECT_THROW(RemoveFloatingPatches(again, nx, ny, std::vector<float>(3, 0.0f), FloatingPatchOptions{}), Error);
}

}  // namespace
}  // namespace skyfall
