#include "pipeline/view_masks.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/error.h"
#include "core/pinhole.h"

namespace skyfall {
namespace {

// A square tile `side_m` wide of 0.5 m cells at 0 m with one 12 m block
// over x0-x1, y0-y1 [m]; colour(x, y, on_block) colours each cell.
template <class Colour>
DenseCells TileWithBlock(int side_m, float x0, float x1, float y0, float y1, Colour colour) {
  DenseCells cells;
  cells.cell_m = 0.5;
  for (int j = 0; j < 2 * side_m; ++j)
    for (int i = 0; i < 2 * side_m; ++i) {
      const float x = 0.25f + 0.5f * i, y = 0.25f + 0.5f * j;
      const bool block = x > x0 && x < x1 && y > y0 && y < y1;
      cells.points.emplace_back(x, y, block ? 12.0f : 0.0f);
      cells.colours.push_back(colour(x, y, block));
      cells.filled.push_back(0);
    }
  return cells;
}

// A 40 m x 40 m tile with a 12 m block (x 20-30 m, y 10-30 m), seen
// obliquely from the south by a view that also sees about 20 m of ground
// beyond the tile on every side.
TEST(MaskBeyondReconstruction, PixelsPastTheDenseHeightsAreMaskedWallsAndTileKept) {
  const DenseCells cells =
      TileWithBlock(40, 20, 30, 10, 30, [](float, float, bool) { return Eigen::Vector3f(0.5f, 0.5f, 0.5f); });
  TrainView view;
  view.camera = LookAtCamera({20, -180, 250}, {20, 20, 0}, 14.0, 96, 96);
  view.valid.assign(96 * 96, 1);
  view.valid[0] = 0;  // no data there: stays masked, and is not counted
  view.rgb.assign(3 * 96 * 96, 0.5f);
  std::vector<TrainView> views = {view};
  const double fraction = MaskBeyondReconstruction(cells, 1.0, RasterOptions(), &views);
  const std::vector<std::uint8_t>& valid = views[0].valid;
  auto valid_at = [&](const Eigen::Vector3d& enu) {
    const Eigen::Vector2d px = views[0].camera.Project(enu);
    const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
    EXPECT_TRUE(x >= 0 && x < 96 && y >= 0 && y < 96) << enu.transpose() << " is outside the view";
    return valid[static_cast<std::size_t>(y) * 96 + x] != 0;
  };
  // The tile's ground, the block's roof and the wall the view faces are kept.
  for (double x : {4.0, 12.0, 36.0})
    for (double y : {4.0, 20.0, 36.0}) EXPECT_TRUE(valid_at({x, y, 0})) << x << ", " << y;
  EXPECT_TRUE(valid_at({25, 20, 12}));
  for (double z : {2.0, 6.0, 10.0}) EXPECT_TRUE(valid_at({25, 10, z})) << "south wall at " << z << " m";
  // Ground 4 m and more beyond the tile is masked on every side.
  for (const Eigen::Vector3d& beyond : {Eigen::Vector3d(-4, 20, 0), Eigen::Vector3d(44, 20, 0),
                                        Eigen::Vector3d(20, -4, 0), Eigen::Vector3d(20, 46, 0),
                                        Eigen::Vector3d(-10, -10, 0)})
    EXPECT_FALSE(valid_at(beyond)) << beyond.transpose();
  EXPECT_EQ(valid[0], 0);
  const double masked = static_cast<double>(std::count(valid.begin(), valid.end(), 0) - 1) / (96.0 * 96.0 - 1);
  EXPECT_NEAR(fraction, masked, 1e-12);
  EXPECT_GT(fraction, 0.3);  // the view's fringe
  EXPECT_LT(fraction, 0.95);
  // Without dense heights nothing is known, so nothing is masked.
  std::vector<TrainView> untouched = {view};
  EXPECT_EQ(MaskBeyondReconstruction(DenseCells(), 1.0, RasterOptions(), &untouched), 0.0);
  EXPECT_EQ(untouched[0].valid, view.valid);
}

// A 60 m x 60 m tile: ground in 2 m squares of assorted colours (hashed
// from the square), a grey 10 m block 12 m tall.
DenseCells ColouredTile() {
  return TileWithBlock(60, 35, 45, 35, 45, [](float x, float y, bool block) {
    if (block) return Eigen::Vector3f(0.75f, 0.75f, 0.72f);
    const unsigned h = (static_cast<unsigned>(x / 2) * 73856093u) ^ (static_cast<unsigned>(y / 2) * 19349663u);
    return Eigen::Vector3f(0.1f + 0.5f * ((h >> 3) % 97) / 96.0f, 0.1f + 0.5f * ((h >> 11) % 89) / 88.0f,
                           0.1f + 0.4f * ((h >> 19) % 83) / 82.0f);
  });
}

// A green 10 m square of ground (x 10-20 m, y 45-55 m) is lit in view 4 only
// and in shade on every other date (the sun moved): brighter there than on
// any other date, but in its own colour, not white.
bool InShadeExceptInView4(const Eigen::Vector3f& p) { return p.x() > 10 && p.x() < 20 && p.y() > 45 && p.y() < 55; }

std::vector<TrainView> ViewsOf(const DenseCells& cells) {
  const Eigen::Vector3d target(30, 30, 0);
  std::vector<TrainView> views;
  for (int k = 0; k < 5; ++k) {
    std::vector<Eigen::Vector3f> colours = cells.colours;
    for (std::size_t i = 0; i < colours.size(); ++i)
      if (InShadeExceptInView4(cells.points[i])) colours[i] = Eigen::Vector3f(0.2f, 0.5f, 0.15f) * (k == 4 ? 1.0f : 0.35f);
    GaussianCloud scene = InitializeFromPoints(cells.points, colours, 0.5, 1);
    for (float& logit : scene.opacity_logits) logit = 4.6f;
    const double azimuth = 2 * M_PI * k / 5 + 0.3, elevation = M_PI / 3, range = 250;
    const Eigen::Vector3d eye = target + range * Eigen::Vector3d(std::cos(elevation) * std::sin(azimuth),
                                                                 std::cos(elevation) * std::cos(azimuth),
                                                                 std::sin(elevation));
    TrainView v;
    v.name = "view" + std::to_string(k);
    v.camera = LookAtCamera(eye, target, 14.0, 96, 96);
    v.rgb = RenderGaussians(scene, v.camera, RasterOptions()).rgb;
    const float gain[3] = {0.8f + 0.1f * k, 1.0f, 1.2f - 0.08f * k};
    for (std::size_t p = 0; p < v.rgb.size(); ++p) v.rgb[p] = std::min(1.0f, v.rgb[p] * gain[p % 3]);
    v.valid.assign(96 * 96, 1);
    views.push_back(v);
  }
  return views;
}

// Whitens view `v` towards 0.95 inside a disc, fully within 0.7 of its
// radius and fading to nothing at its rim, like a cumulus' soft edge.
void AddCloud(TrainView* v, double cx, double cy, double radius_px) {
  for (int y = 0; y < 96; ++y)
    for (int x = 0; x < 96; ++x) {
      const double r = std::hypot(x - cx, y - cy) / radius_px;
      const float a = static_cast<float>(std::clamp((1.0 - r) / 0.3, 0.0, 1.0));
      for (int c = 0; c < 3; ++c) {
        float& value = v->rgb[3 * (static_cast<std::size_t>(y) * 96 + x) + c];
        value = (1 - a) * value + a * 0.95f;
      }
    }
}

std::size_t Masked(const TrainView& v) { return static_cast<std::size_t>(std::count(v.valid.begin(), v.valid.end(), 0)); }

TEST(MaskClouds, ACloudOnOneDateIsMaskedAndTheGroundsColoursAreNot) {
  const DenseCells cells = ColouredTile();
  std::vector<TrainView> views = ViewsOf(cells);
  const Eigen::Vector2d centre = views[1].camera.Project({30, 30, 0});
  constexpr double kRadiusPx = 22;
  const std::vector<float> clear = views[1].rgb;
  AddCloud(&views[1], centre.x(), centre.y(), kRadiusPx);
  // A car-sized white glint on another date: a transient too small to mask.
  for (int y = 40; y < 42; ++y)
    for (int x = 30; x < 34; ++x)
      for (int c = 0; c < 3; ++c) views[3].rgb[3 * (y * 96 + x) + c] = 0.98f;
  TrainView held_out = views[0];
  held_out.name = "held_out";
  held_out.held_out = true;
  AddCloud(&held_out, 48, 48, kRadiusPx);
  views.push_back(held_out);

  CloudMaskOptions options;
  options.enabled = true;
  const std::vector<RenderOutput<float>> covers = RenderDenseCover(cells, 1.0, RasterOptions(), views);
  const std::vector<double> fractions = MaskClouds(cells, covers, options, &views);

  // The cloud's core (where it brightens the pixel by 0.2 or more) is masked.
  std::size_t core = 0, core_masked = 0, outside = 0, outside_masked = 0;
  const double grow_px = 4;  // grow_m 2 m at about 0.64 m per pixel, and a pixel of rounding
  for (int y = 0; y < 96; ++y)
    for (int x = 0; x < 96; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * 96 + x;
      const double r = std::hypot(x - centre.x(), y - centre.y());
      const bool masked = views[1].valid[p] == 0;
      float added = 0;
      for (int c = 0; c < 3; ++c) added += (views[1].rgb[3 * p + c] - clear[3 * p + c]) / 3;
      if (added >= 0.2f) {
        ++core;
        core_masked += masked;
      } else if (r > kRadiusPx + grow_px) {
        ++outside;
        outside_masked += masked;
      }
    }
  EXPECT_GE(core_masked, 0.95 * core) << core_masked << " of " << core;
  // Beyond the cloud and its grown fringe, only the block's walls that face
  // this view alone join it (unjudged pixels within 5 m): about 1% of the
  // view; ground beyond that is kept.
  EXPECT_LE(outside_masked, 0.02 * outside) << outside_masked << " of " << outside;
  EXPECT_NEAR(fractions[1], static_cast<double>(Masked(views[1])) / (96.0 * 96.0), 1e-12);
  // Clear dates, the white glint and the ground lit on one date among them,
  // keep (nearly) every pixel.
  for (int k : {0, 2, 3, 4}) EXPECT_LE(fractions[k], 0.01) << views[k].name;
  for (int y = 40; y < 42; ++y)
    for (int x = 30; x < 34; ++x) EXPECT_EQ(views[3].valid[y * 96 + x], 1) << x << ", " << y;
  const Eigen::Vector2d lit = views[4].camera.Project({15, 50, 0});
  EXPECT_EQ(views[4].valid[static_cast<std::size_t>(std::lround(lit.y())) * 96 + std::lround(lit.x())], 1);
  // The held-out view is scored as given.
  EXPECT_EQ(Masked(views[5]), 0u);
  EXPECT_EQ(fractions[5], 0.0);
}

TEST(MaskClouds, TooFewTrainingViewsOrSwitchedOffMaskNothing) {
  const DenseCells cells = ColouredTile();
  std::vector<TrainView> views = ViewsOf(cells);
  AddCloud(&views[1], 48, 48, 22);
  const std::vector<RenderOutput<float>> covers = RenderDenseCover(cells, 1.0, RasterOptions(), views);
  const CloudMaskOptions off;  // the default
  std::vector<TrainView> untouched = views;
  EXPECT_EQ(MaskClouds(cells, covers, off, &untouched), std::vector<double>(5, 0.0));
  for (const TrainView& v : untouched) EXPECT_EQ(Masked(v), 0u) << v.name;
  // Two training views: a brighter pixel could be either one's; nothing is judged.
  std::vector<TrainView> pair = views;
  for (int k : {2, 3, 4}) pair[k].held_out = true;
  CloudMaskOptions on;
  on.enabled = true;
  EXPECT_EQ(MaskClouds(cells, covers, on, &pair), std::vector<double>(5, 0.0));
  for (const TrainView& v : pair) EXPECT_EQ(Masked(v), 0u) << v.name;
  CloudMaskOptions bad = on;
  bad.max_chroma = 1.5;
  EXPECT_THROW(MaskClouds(cells, covers, bad, &untouched), Error);
}

}  // namespace
}  // namespace skyfall
