#include "products/dsm.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "products/dsm_report.h"
#include "tests/test_support.h"
#include "ingest/geo.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

DsmGrid JaxTruth() {
  const fs::path t = Dfc2019Root() / "Track3-Truth";
  return ReadDsm((t / "JAX_068_DSM.tif").string(), (t / "JAX_068_DSM.txt").string(), 32617);
}

// pred(c, r) = truth(c - dx, r - dy) + dz: the truth moved by (dx, dy) pixels and dz metres.
DsmGrid Shifted(const DsmGrid& t, int dx, int dy, float dz) {
  DsmGrid p = t;
  for (int r = 0; r < t.height_px; ++r)
    for (int c = 0; c < t.width_px; ++c) {
      const int sc = c - dx, sr = r - dy;
      p.height_m[static_cast<size_t>(r) * t.width_px + c] =
          sc >= 0 && sr >= 0 && sc < t.width_px && sr < t.height_px ? t.At(sc, sr) + dz : NAN;
    }
  return p;
}

TEST(Dsm, RecoversAKnownShiftAndBiasWithZeroError) {
  SKYFALL_REQUIRE_DFC2019();
  const DsmGrid truth = JaxTruth();
  const DsmComparison r = CompareDsm(Shifted(truth, 3, -2, 1.7f), truth, nullptr, DsmCompareOptions{});
  EXPECT_EQ(r.shift_col_px, 3);
  EXPECT_EQ(r.shift_row_px, -2);
  EXPECT_NEAR(r.bias_m, 1.7, 1e-5);
  EXPECT_NEAR(r.z_offset_m, 1.7, 1e-5);
  EXPECT_LT(r.mae_m, 1e-5);  // float storage of heights ~30 m: ~2e-6 m
  EXPECT_LT(r.rmse_m, 1e-5);
  // Unshifted, every building edge of the city is off by 3 and 2 pixels.
  EXPECT_GT(r.mae_at_zero_shift_m, 0.5);
  const DsmComparison same = CompareDsm(truth, truth, nullptr, DsmCompareOptions{});
  EXPECT_EQ(same.mae_at_zero_shift_m, same.mae_m);
  EXPECT_NEAR(r.within_fraction, 1.0, 1e-12);
  // Only the band the shift moved out of the grid is missing.
  EXPECT_NEAR(r.completeness, (512.0 - 3) * (512.0 - 2) / (512.0 * 512.0), 1e-9);
}

// A few large errors (2% of the pixels 30 m low: missed roofs) do not move
// the vertical offset removed, so every other pixel keeps zero error; with
// the mean removed they would all read 0.6 m off.
TEST(Dsm, AFewLargeErrorsDoNotShiftTheCorrectPixels) {
  SKYFALL_REQUIRE_DFC2019();
  const DsmGrid truth = JaxTruth();
  DsmGrid pred = Shifted(truth, 0, 0, 0.25f);
  std::size_t holes = 0, valid = 0;
  for (std::size_t p = 0; p < pred.height_m.size(); ++p) {
    if (!std::isfinite(pred.height_m[p])) continue;
    ++valid;
    if (p % 50 == 7) {
      pred.height_m[p] -= 30.0f;
      ++holes;
    }
  }
  DsmCompareOptions o;
  o.max_shift_px = 0;  // the errors are vertical only
  const DsmComparison r = CompareDsm(pred, truth, nullptr, o);
  EXPECT_NEAR(r.z_offset_m, 0.25, 1e-5);
  EXPECT_NEAR(r.bias_m, 0.25 - 30.0 * holes / valid, 1e-3);
  EXPECT_NEAR(r.mae_m, 30.0 * holes / valid, 1e-3);  // only the holes count
  EXPECT_LT(r.median_abs_m, 1e-5);
  EXPECT_NEAR(r.within_fraction, 1.0 - static_cast<double>(holes) / valid, 1e-6);
}

TEST(Dsm, LargerShiftsAreFoundThroughThePyramid) {
  SKYFALL_REQUIRE_DFC2019();
  const DsmGrid truth = JaxTruth();
  // 8 px is beyond +-5 at full resolution, within reach at half resolution.
  const DsmComparison r = CompareDsm(Shifted(truth, -8, 7, -0.4f), truth, nullptr, DsmCompareOptions{});
  EXPECT_EQ(r.shift_col_px, -8);
  EXPECT_EQ(r.shift_row_px, 7);
  EXPECT_LT(r.mae_m, 1e-5);
}

TEST(Dsm, WaterIsMaskedAndNodataLowersCompleteness) {
  SKYFALL_REQUIRE_DFC2019();
  const DsmGrid truth = JaxTruth();
  DsmGrid pred = truth;
  std::vector<float> cls(truth.height_m.size(), 2.0f);
  for (int r = 100; r < 150; ++r)
    for (int c = 200; c < 260; ++c) {
      cls[static_cast<size_t>(r) * 512 + c] = 9.0f;    // water
      pred.height_m[static_cast<size_t>(r) * 512 + c] += 30.0f;  // wildly wrong over water
    }
  for (int r = 300; r < 400; ++r)
    for (int c = 300; c < 400; ++c) pred.height_m[static_cast<size_t>(r) * 512 + c] = NAN;  // not reconstructed
  const DsmComparison masked = CompareDsm(pred, truth, &cls, DsmCompareOptions{});
  EXPECT_EQ(masked.shift_col_px, 0);
  EXPECT_LT(masked.mae_m, 1e-6);
  const double truth_valid = 512.0 * 512.0 - 50 * 60;
  EXPECT_NEAR(masked.completeness, (truth_valid - 100 * 100) / truth_valid, 1e-9);
  DsmCompareOptions no_mask;
  no_mask.mask_water = false;
  EXPECT_GT(CompareDsm(pred, truth, &cls, no_mask).mae_m, 0.3);  // the water block counts now
}

TEST(Dsm, GeoTiffRoundTripKeepsCrsAndGrid) {
  SKYFALL_REQUIRE_DFC2019();
  const DsmGrid truth = JaxTruth();
  const fs::path dir = ScratchDir("dsm");
  WriteDsm((dir / "dsm.tif").string(), truth);
  const DsmGrid back = ReadDsm((dir / "dsm.tif").string());
  EXPECT_EQ(back.epsg, 32617);
  EXPECT_DOUBLE_EQ(back.upper_left_easting_m, 436078.995946);
  EXPECT_DOUBLE_EQ(back.upper_left_northing_m, 3357495.999923 + 256.0);
  EXPECT_DOUBLE_EQ(back.gsd_m, 0.5);
  EXPECT_EQ(back.height_m, truth.height_m);
  EXPECT_EQ(ReadRasterInfo((dir / "dsm.tif").string()).driver, "GTiff");
}

TEST(Dsm, RasterizedFlatSceneGivesItsHeight) {
  // A 120 m square of small opaque, flat Gaussians at ENU height 12 m.
  const GeodeticPoint origin{-81.66375, 30.34881, 1.5};
  GaussianCloud scene;
  for (int i = -60; i <= 60; ++i)
    for (int j = -60; j <= 60; ++j) {
      scene.means.emplace_back(static_cast<float>(i), static_cast<float>(j), 12.0f);
      scene.log_scales.emplace_back(std::log(0.8f), std::log(0.8f), std::log(0.02f));
      scene.rotations.emplace_back(1.0f, 0.0f, 0.0f, 0.0f);
      scene.opacity_logits.push_back(5.0f);
      std::array<float, 12> sh{};
      scene.sh.push_back(sh);
    }
  const UtmZone zone = StandardUtmZone(origin.lon_deg, origin.lat_deg);
  const Eigen::Vector2d en = UtmFromGeodetic(zone, origin.lon_deg, origin.lat_deg);
  DsmGrid grid;
  grid.width_px = grid.height_px = 200;
  grid.gsd_m = 0.5;
  grid.epsg = zone.Epsg();
  grid.upper_left_easting_m = en.x() - 50;
  grid.upper_left_northing_m = en.y() + 50;
  RasterizeDsm(scene, origin, DsmExportOptions{}, &grid);
  int checked = 0;
  for (int r = 10; r < 190; r += 7)
    for (int c = 10; c < 190; c += 7) {
      // ENU height 12 m above a 1.5 m origin; the ENU plane departs from the
      // ellipsoid by d^2 / 2R < 1 mm here.
      EXPECT_NEAR(grid.At(c, r), 13.5, 0.02) << c << "," << r;
      ++checked;
    }
  EXPECT_GT(checked, 600);
}

// Boxes of Gaussians with random sizes, rotations, heights and colours over
// 300 m, and a 100 m grid off its centre.
struct BlockyScene {
  GeodeticPoint origin{-81.66375, 30.34881, 1.5};
  GaussianCloud scene;
  DsmGrid grid;
};
BlockyScene MakeBlockyScene() {
  BlockyScene b;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int k = 0; k < 40000; ++k) {
    const float x = 300.0f * u(rng) - 150.0f, y = 300.0f * u(rng) - 150.0f;
    const float roof = std::floor(x / 25.0f) * std::floor(y / 25.0f) > 0 ? 20.0f * u(rng) : 0.0f;
    b.scene.means.emplace_back(x, y, roof + 0.3f * u(rng));
    b.scene.log_scales.emplace_back(std::log(0.2f + 2.0f * u(rng)), std::log(0.2f + u(rng)), std::log(0.05f));
    Eigen::Vector4f q(u(rng), u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f);
    b.scene.rotations.push_back(q.normalized());
    b.scene.opacity_logits.push_back(6.0f * u(rng) - 1.0f);
    std::array<float, 12> sh{};
    for (int c = 0; c < 3; ++c) sh[c * 4] = u(rng) - 0.5f;
    b.scene.sh.push_back(sh);
  }
  const UtmZone zone = StandardUtmZone(b.origin.lon_deg, b.origin.lat_deg);
  const Eigen::Vector2d en = UtmFromGeodetic(zone, b.origin.lon_deg, b.origin.lat_deg);
  b.grid.width_px = b.grid.height_px = 200;
  b.grid.gsd_m = 0.5;
  b.grid.epsg = zone.Epsg();
  b.grid.upper_left_easting_m = en.x() - 20;
  b.grid.upper_left_northing_m = en.y() + 70;
  return b;
}

TEST(Dsm, AGridRendersTheSameFromTheGaussiansThatMeetIt) {
  BlockyScene b = MakeBlockyScene();
  DsmGrid whole = b.grid, cropped = b.grid;
  std::vector<float> whole_rgb, cropped_rgb;
  RasterizeDsm(b.scene, b.origin, DsmExportOptions{}, &whole, &whole_rgb);
  const GaussianCloud part = CropCloud(b.scene, MeetsGrid(EnuBoxOfGrid(b.grid, b.origin), b.grid.gsd_m));
  EXPECT_LT(part.size(), b.scene.size() / 4);  // the grid is a ninth of the scene's area
  RasterizeDsm(part, b.origin, DsmExportOptions{}, &cropped, &cropped_rgb);
  ASSERT_EQ(whole.height_m.size(), cropped.height_m.size());
  std::size_t valid = 0;
  for (std::size_t p = 0; p < whole.height_m.size(); ++p) {
    valid += std::isfinite(whole.height_m[p]);
    // Byte for byte: the same Gaussians blend in the same order.
    EXPECT_EQ(std::memcmp(&whole.height_m[p], &cropped.height_m[p], sizeof(float)), 0) << p;
  }
  EXPECT_GT(valid, whole.height_m.size() / 2);
  EXPECT_EQ(std::memcmp(whole_rgb.data(), cropped_rgb.data(), whole_rgb.size() * sizeof(float)), 0);
}

TEST(Dsm, ARenderInBlocksMatchesOneRender) {
  BlockyScene b = MakeBlockyScene();
  DsmGrid whole = b.grid, blocks = b.grid;
  std::vector<float> whole_rgb, blocks_rgb;
  RasterizeDsm(b.scene, b.origin, DsmExportOptions{}, &whole, &whole_rgb);
  std::size_t reads = 0;
  const GaussiansMeeting source = [&](const GaussianFilter& keep) {
    ++reads;
    return CropCloud(b.scene, keep);
  };
  std::size_t visited = 0;
  RasterizeDsmInBlocks(source, b.origin, DsmExportOptions{}, &blocks, &blocks_rgb,
                       [&](const GridBlock& block, const GaussianCloud& part) {
                         ++visited;
                         EXPECT_GT(part.size(), 0u) << block.col0 << "," << block.row0;
                       },
                       /*block_px=*/64);
  EXPECT_EQ(reads, 16u);  // 200 px in blocks of 64: 4 x 4
  EXPECT_EQ(visited, 16u);
  // Blocks carry the grid's figures, never its pixels (a city's raster
  // once per block was the merge's peak).
  for (const GridBlock& block : GridBlocks(blocks, 64)) {
    EXPECT_EQ(block.grid.height_m.capacity(), 0u);
    EXPECT_EQ(block.grid.epsg, blocks.epsg);
    EXPECT_EQ(block.grid.gsd_m, blocks.gsd_m);
    EXPECT_EQ(block.grid.upper_left_easting_m, blocks.upper_left_easting_m + block.col0 * blocks.gsd_m);
  }
  // A window of one camera's image: the same Gaussians blend in the same
  // order and only the float rounding of their image positions differs
  // (their float offsets from a window's corner, not the image's). Heights
  // then agree to a millimetre, except where that rounding moves the
  // crossing of the median past 0.5 from one Gaussian to another, or a
  // pixel's opacity across min_alpha: about 5 pixels in a thousand in this
  // scene of random overlapping layers. A block pasted one pixel off, or
  // rendered from too few Gaussians, changes most of them.
  constexpr double kRoundingM = 1e-3;
  constexpr double kFlipFraction = 0.01;
  std::size_t flips = 0, both = 0;
  for (std::size_t p = 0; p < whole.height_m.size(); ++p) {
    const bool a = std::isfinite(whole.height_m[p]), c = std::isfinite(blocks.height_m[p]);
    if (a != c) ++flips;
    if (!a || !c) continue;
    ++both;
    if (std::abs(whole.height_m[p] - blocks.height_m[p]) > kRoundingM) ++flips;
  }
  EXPECT_GT(both, whole.height_m.size() / 2);
  EXPECT_LE(flips, kFlipFraction * whole.height_m.size()) << flips;
}

TEST(Dsm, ACoarseGridReadsEachCellAtItsCentre) {
  // Ground at ENU height 0 (Gaussians every 2 m) and a 40 m roof 15 m up
  // (every 0.5 m, 0.3 m wide), on a 2.1 m grid: a truth sampled at cell
  // centres has the roof exactly where a cell's centre lies on it. Rendered
  // at one sample per cell, the anti-aliasing dilation of 0.3 px^2 (1.15 m
  // sigma at 2.1 m) spread the roof over the ground cells within about
  // 1.5 m of its edge.
  const GeodeticPoint origin{-81.66375, 30.34881, 1.5};
  GaussianCloud scene;
  auto add = [&](float x, float y, float z, float sigma) {
    scene.means.emplace_back(x, y, z);
    scene.log_scales.emplace_back(std::log(sigma), std::log(sigma), std::log(0.02f));
    scene.rotations.emplace_back(1.0f, 0.0f, 0.0f, 0.0f);
    scene.opacity_logits.push_back(5.0f);
    scene.sh.push_back(std::array<float, 12>{});
  };
  constexpr float kRoofHalfM = 20.0f, kRoofM = 15.0f;
  for (float x = -230; x <= 230; x += 2)
    for (float y = -240; y <= 240; y += 2) add(x, y, 0.0f, 1.2f);
  for (float x = -kRoofHalfM; x <= kRoofHalfM; x += 0.5f)
    for (float y = -kRoofHalfM; y <= kRoofHalfM; y += 0.5f) add(x, y, kRoofM, 0.3f);
  const UtmZone zone = StandardUtmZone(origin.lon_deg, origin.lat_deg);
  const Eigen::Vector2d en = UtmFromGeodetic(zone, origin.lon_deg, origin.lat_deg);
  DsmGrid grid;
  grid.gsd_m = 2.1;
  // Wide enough that the render runs in more than one strip of rows.
  grid.width_px = 200;
  grid.height_px = 220;
  grid.epsg = zone.Epsg();
  grid.upper_left_easting_m = en.x() - 0.5 * grid.width_px * grid.gsd_m + 0.37;
  grid.upper_left_northing_m = en.y() + 0.5 * grid.height_px * grid.gsd_m - 0.81;
  RasterizeDsm(scene, origin, DsmExportOptions{}, &grid);
  const EnuFrame frame(origin);
  // [m] a cell whose centre lies further than this outside the roof's
  // Gaussians reads the ground, further inside the roof: the roof's own
  // Gaussians reach 0.35 m beyond their centres at half opacity, and the
  // finer render's dilation adds about 0.2 m.
  constexpr double kEdgeM = 0.8;
  constexpr double kHeightToleranceM = 0.05;  // flat surfaces; the ENU plane bends < 1 cm here
  int near_outside = 0, inside = 0;
  for (int r = 0; r < grid.height_px; ++r)
    for (int c = 0; c < grid.width_px; ++c) {
      const Eigen::Vector2d ll = GeodeticFromUtm(zone, grid.upper_left_easting_m + (c + 0.5) * grid.gsd_m,
                                                 grid.upper_left_northing_m - (r + 0.5) * grid.gsd_m);
      const Eigen::Vector3d p = frame.EnuFromGeodetic({ll.x(), ll.y(), origin.height_m});
      // Signed distance of the centre outside the roof's box (negative inside).
      const double dx = std::abs(p.x()) - kRoofHalfM, dy = std::abs(p.y()) - kRoofHalfM;
      const double outside_m = dx > 0 || dy > 0 ? std::hypot(std::max(dx, 0.0), std::max(dy, 0.0)) : std::max(dx, dy);
      const double ground = origin.height_m, roof = origin.height_m + kRoofM;
      if (std::abs(p.x()) > 200 || std::abs(p.y()) > 200) continue;  // the ground's own edge
      if (outside_m > kEdgeM) {
        EXPECT_NEAR(grid.At(c, r), ground, kHeightToleranceM) << c << "," << r << ": " << outside_m << " m outside";
        if (outside_m < 1.6) ++near_outside;
      } else if (outside_m < -kEdgeM) {
        EXPECT_NEAR(grid.At(c, r), roof, kHeightToleranceM) << c << "," << r;
        ++inside;
      }
    }
  // The cells that one sample per cell put on the roof are there to check.
  EXPECT_GT(near_outside, 20);
  EXPECT_GT(inside, 250);
}

TEST(Dsm, ComparisonProductsAreWritten) {
  SKYFALL_REQUIRE_DFC2019();
  const DsmGrid truth = JaxTruth();
  const DsmComparison r = CompareDsm(Shifted(truth, 1, 1, 0.5f), truth, nullptr, DsmCompareOptions{});
  const fs::path dir = ScratchDir("report");
  WriteDsmComparison(r, truth, DsmCompareOptions{}, {"p.tif", "t.tif", ""}, dir.string());
  for (const char* f : {"report.json", "report.csv", "error_map.tif", "error_map.png", "error_histogram.png"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  EXPECT_EQ(ReadRasterInfo((dir / "error_map.png").string()).bands, 3);
}

TEST(Dsm, AGridOfBoundsSamplesAnotherGridByPixelCentre) {
  // 10 m x 4 m at 1 m: 10 x 4 pixels, upper-left corner at (min_e, max_n).
  DsmGrid source = GridOfBounds(500000, 3000000, 500010, 3000004, 1.0, 32617, "test");
  ASSERT_EQ(source.width_px, 10);
  ASSERT_EQ(source.height_px, 4);
  EXPECT_EQ(source.upper_left_northing_m, 3000004);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 10; ++c) source.height_m[static_cast<size_t>(r) * 10 + c] = static_cast<float>(10 * r + c);
  // A target two pixels east and one south: its (0, 0) is the source's (2, 1);
  // its last two columns and last row lie outside the source.
  const DsmGrid target = GridOfBounds(500002, 2999999, 500012, 3000003, 1.0, 32617, "test");
  const DsmGrid sampled = SampleOnGrid(source, target, "source.tif");
  EXPECT_EQ(sampled.At(0, 0), source.At(2, 1));
  EXPECT_EQ(sampled.At(7, 2), source.At(9, 3));
  EXPECT_TRUE(std::isnan(sampled.At(8, 0)));
  EXPECT_TRUE(std::isnan(sampled.At(0, 3)));
  EXPECT_NE(ErrorText([&] { SampleOnGrid(source, GridOfBounds(0, 0, 4, 4, 0.5, 32617, "t"), "source.tif"); })
                .find("source.tif"),
            std::string::npos);
  EXPECT_NE(ErrorText([] { GridOfBounds(1, 0, 0, 4, 0.5, 32617, "--bounds"); }).find("--bounds"), std::string::npos);
  EXPECT_NE(ErrorText([] { GridOfBounds(0, 0, 4, 4, 0, 32617, "--bounds"); }).find("GSD"), std::string::npos);
}

}  // namespace
}  // namespace skyfall
