#include "products/land_cover.h"

#include <gdal.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/error.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

constexpr int kN = 80;            // grid side [px]
constexpr double kGsdM = 0.5;
constexpr float kGroundM = 12.0f;  // ellipsoidal, as a sea-level AOI's

std::size_t Px(int col, int row) { return static_cast<std::size_t>(row) * kN + col; }

DsmGrid Grid(float fill) {
  DsmGrid g;
  g.width_px = g.height_px = kN;
  g.gsd_m = kGsdM;
  g.epsg = 32617;
  g.upper_left_easting_m = 435000;
  g.upper_left_northing_m = 3358000;
  g.height_m.assign(static_cast<std::size_t>(kN) * kN, fill);
  return g;
}

// A scene of ground, one flat grey roof (columns 8..35, rows 8..35, 10 m
// up), one grey roof cluttered with plant (rows 48..75, as rough as a
// crown), and one green crown (a disc of 9 px radius around (58, 58),
// 6-9 m up, rough), on a flat DTM; colours in [0, 1].
struct Scene {
  DsmGrid dsm = Grid(kGroundM), dtm = Grid(kGroundM);
  std::vector<float> rgb = std::vector<float>(3 * kN * kN, 0.0f);
  std::vector<float> truth = std::vector<float>(kN * kN, 2.0f);  // DFC2019 codes
};
bool InRoof(int col, int row) { return col >= 8 && col < 36 && row >= 8 && row < 36; }
bool InRoughRoof(int col, int row) { return col >= 8 && col < 36 && row >= 48 && row < 76; }
bool InCrown(int col, int row) { return std::hypot(col - 58, row - 58) < 9; }

Scene MakeScene() {
  Scene s;
  std::mt19937 random(7);
  std::uniform_real_distribution<float> crown_m(6.0f, 9.0f), tint(-0.03f, 0.03f);
  for (int row = 0; row < kN; ++row)
    for (int col = 0; col < kN; ++col) {
      const std::size_t p = Px(col, row);
      std::array<float, 3> c = {0.45f, 0.42f, 0.35f};  // bare soil, asphalt
      if (InRoof(col, row)) {
        s.dsm.height_m[p] = kGroundM + 10.0f;
        c = {0.6f, 0.6f, 0.62f};
        s.truth[p] = 6;
      } else if (InRoughRoof(col, row)) {
        s.dsm.height_m[p] = kGroundM + 10.0f + (((col / 2 + row / 2) % 2) ? 0.8f : -0.8f);
        c = {0.55f, 0.55f, 0.5f};
        s.truth[p] = 6;
      } else if (InCrown(col, row)) {
        s.dsm.height_m[p] = kGroundM + crown_m(random);
        c = {0.20f, 0.32f, 0.15f};
        s.truth[p] = 5;
      }
      for (int b = 0; b < 3; ++b) s.rgb[3 * p + b] = c[b] + tint(random);
    }
  return s;
}

TEST(PlaneResidual, IsZeroOnATiltedPlaneAndTheAmplitudeOnACheckerboard) {
  DsmGrid plane = Grid(0), checker = Grid(0);
  for (int row = 0; row < kN; ++row)
    for (int col = 0; col < kN; ++col) {
      plane.height_m[Px(col, row)] = 3000.0f + 0.4f * col - 0.25f * row;  // a high AOI's ellipsoidal heights
      checker.height_m[Px(col, row)] = ((col + row) % 2) ? 0.5f : -0.5f;
    }
  const std::vector<float> flat = PlaneResidualM(plane, 2), rough = PlaneResidualM(checker, 2);
  // float heights near 3,000 m carry about 0.2 mm of rounding
  constexpr float kFloatRoundingM = 1e-3f;
  for (std::size_t p = 0; p < flat.size(); ++p) ASSERT_NEAR(flat[p], 0.0f, kFloatRoundingM) << p;
  // Interior window of 25 cells: 13 of one sign, 12 of the other; the
  // plane's offset takes the mean 0.02 m, the residual stays ~0.5 m.
  EXPECT_NEAR(rough[Px(40, 40)], 0.5f, 0.01f);
}

TEST(PlaneResidual, SkipsHolesAndIsNanWithTooFewHeights) {
  DsmGrid g = Grid(NAN);
  g.height_m[Px(10, 10)] = 5;
  g.height_m[Px(11, 10)] = 5;
  g.height_m[Px(10, 11)] = 5;
  const std::vector<float> r = PlaneResidualM(g, 1);
  EXPECT_TRUE(std::isnan(r[Px(10, 10)]));  // 3 heights: no residual to speak of
  g.height_m[Px(11, 11)] = 5;
  EXPECT_NEAR(PlaneResidualM(g, 1)[Px(10, 10)], 0.0f, 1e-6f);
  EXPECT_TRUE(std::isnan(PlaneResidualM(g, 1)[Px(30, 30)]));
}

TEST(ExcessGreen, IsTheNormalisedIndexAndNanWhereEmptyOrBlack) {
  const std::vector<float> rgb = {0.2f, 0.4f, 0.2f, 0.5f, 0.5f, 0.5f, 0, 0, 0, NAN, NAN, NAN};
  const std::vector<float> g = ExcessGreen(rgb);
  ASSERT_EQ(g.size(), 4u);
  EXPECT_NEAR(g[0], 0.4f / 0.8f, 1e-6f);
  EXPECT_NEAR(g[1], 0.0f, 1e-6f);
  EXPECT_TRUE(std::isnan(g[2]));
  EXPECT_TRUE(std::isnan(g[3]));
}

// Share of the cells of one truth class that got `code`.
double Share(const LandCoverMap& map, const Scene& s, float truth, LandCover code) {
  int in = 0, hit = 0;
  for (std::size_t p = 0; p < map.classes.size(); ++p)
    if (s.truth[p] == truth) ++in, hit += map.classes[p] == static_cast<std::uint8_t>(code);
  return static_cast<double>(hit) / in;
}

TEST(LandCover, TellsARoofFromACrownAndBothFromTheGround) {
  const Scene s = MakeScene();
  const LandCoverMap map = ClassifyLandCover(s.dsm, s.dtm, s.rgb, /*colour=*/true, {});
  EXPECT_TRUE(map.colour);
  EXPECT_EQ(Share(map, s, 2, LandCover::kGround), 1.0);
  EXPECT_EQ(Share(map, s, 6, LandCover::kBuilding), 1.0);
  // The crown's rim cells see fewer of its votes than of its neighbours'.
  EXPECT_GT(Share(map, s, 5, LandCover::kHighVegetation), 0.9);
  EXPECT_EQ(map.ground_cells + map.building_cells + map.vegetation_cells + map.above_ground_cells, kN * kN);
  const LandCoverAgreement a = CompareLandCover(map, s.truth, kN, kN, 0, 0);
  EXPECT_EQ(a.building.iou, 1.0);
  EXPECT_GT(a.vegetation.iou, 0.9);
  EXPECT_GT(a.overall_accuracy, 0.98);
}

TEST(LandCover, DoesNotDependOnTheSensorsColourBalance) {
  // A green cast on every cell (another sensor, another date) moves the
  // threshold with it: the relative rule gives the same map, and the rough
  // roof, now greener than a fixed threshold of 0.02 would allow, stays a
  // building.
  Scene s = MakeScene();
  const LandCoverMap before = ClassifyLandCover(s.dsm, s.dtm, s.rgb, true, {});
  for (std::size_t p = 0; p < s.rgb.size() / 3; ++p) s.rgb[3 * p + 1] *= 1.25f;
  const LandCoverMap after = ClassifyLandCover(s.dsm, s.dtm, s.rgb, true, {});
  EXPECT_GT(after.green_threshold, before.green_threshold);
  EXPECT_EQ(after.classes, before.classes);
  EXPECT_GT(ExcessGreen({0.55f, 0.55f * 1.25f, 0.5f})[0], 0.02f);
}

TEST(LandCover, APanchromaticSceneLeavesObjectsUntold) {
  const Scene s = MakeScene();
  const LandCoverMap map = ClassifyLandCover(s.dsm, s.dtm, s.rgb, /*colour=*/false, {});
  EXPECT_FALSE(map.colour);
  EXPECT_EQ(map.building_cells + map.vegetation_cells, 0);
  EXPECT_EQ(Share(map, s, 6, LandCover::kAboveGround), 1.0);
  EXPECT_GT(Share(map, s, 5, LandCover::kAboveGround), 0.99);
  EXPECT_EQ(Share(map, s, 2, LandCover::kGround), 1.0);
}

TEST(LandCover, NoHeightIsNoData) {
  Scene s = MakeScene();
  s.dsm.height_m[Px(1, 1)] = NAN;
  s.dtm.height_m[Px(2, 1)] = NAN;
  const LandCoverMap map = ClassifyLandCover(s.dsm, s.dtm, {}, true, {});
  EXPECT_FALSE(map.colour);  // no colours given
  EXPECT_EQ(map.classes[Px(1, 1)], 0);
  EXPECT_EQ(map.classes[Px(2, 1)], 0);
  DsmGrid other = s.dtm;
  other.width_px = 10;
  EXPECT_THROW(ClassifyLandCover(s.dsm, other, {}, true, {}), Error);
}

TEST(LandCover, AgreementCountsKnownCellsAndAppliesTheShift) {
  LandCoverMap map;
  map.classes = {6, 6, 5, 2, 2, 0};
  const std::vector<float> truth = {6, 5, 5, 2, 65, 6};  // 65: unlabelled, 0: our no data
  const LandCoverAgreement a = CompareLandCover(map, truth, 6, 1, 0, 0);
  EXPECT_EQ(a.cells, 4);
  EXPECT_DOUBLE_EQ(a.building.iou, 0.5);  // 1 both, 2 predicted, 1 truth
  EXPECT_DOUBLE_EQ(a.building.precision, 0.5);
  EXPECT_DOUBLE_EQ(a.vegetation.iou, 0.5);
  EXPECT_DOUBLE_EQ(a.vegetation.recall, 0.5);
  EXPECT_DOUBLE_EQ(a.ground.iou, 1.0);
  EXPECT_DOUBLE_EQ(a.overall_accuracy, 3.0 / 4.0);
  // Predicted cell col + 1 against truth cell col: truth cells 0..3 agree
  // with predictions 1..4; truth cell 4 meets our no data, 5 the edge.
  const LandCoverAgreement shifted = CompareLandCover(map, {6, 5, 2, 2, 6, 6}, 6, 1, 1, 0);
  EXPECT_EQ(shifted.cells, 4);
  EXPECT_DOUBLE_EQ(shifted.overall_accuracy, 1.0);
}

TEST(LandCover, OptionsOutOfRangeNameTheField) {
  LandCoverOptions o;
  o.vote_radius_m = -1;
  EXPECT_NE(ErrorText([&] { o.Check(); }).find("land_cover.vote_radius_m"), std::string::npos);
  o = {};
  o.object_min_m = 0;
  EXPECT_NE(ErrorText([&] { o.Check(); }).find("land_cover.object_min_m"), std::string::npos);
  EXPECT_NO_THROW(LandCoverOptions{}.Check());
}

TEST(LandCover, CogHasCodesAColourTableAndNearestOverviews) {
  const fs::path dir = ScratchDir("land_cover_cog");
  const Scene s = MakeScene();
  DsmGrid dsm = s.dsm, dtm = s.dtm;
  // 600 px a side, so that the COG has overviews to check.
  constexpr int kBig = 600;
  auto grow = [&](DsmGrid* g) {
    DsmGrid big = *g;
    big.width_px = big.height_px = kBig;
    big.height_m.assign(static_cast<std::size_t>(kBig) * kBig, kGroundM);
    for (int row = 0; row < kBig; ++row)
      for (int col = 0; col < kBig; ++col) big.height_m[row * kBig + col] = g->At(col % kN, row % kN);
    *g = big;
  };
  grow(&dsm);
  grow(&dtm);
  std::vector<float> rgb(3 * kBig * kBig);
  for (int row = 0; row < kBig; ++row)
    for (int col = 0; col < kBig; ++col)
      for (int b = 0; b < 3; ++b) rgb[3 * (row * kBig + col) + b] = s.rgb[3 * Px(col % kN, row % kN) + b];
  const LandCoverMap map = ClassifyLandCover(dsm, dtm, rgb, true, {});
  const std::string path = (dir / "classes.tif").string();
  WriteLandCoverCog(path, dsm, map, {{"LAND_COVER_RULE", "test"}});
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  EXPECT_EQ(GDALGetRasterDataType(band), GDT_Byte);
  int has_nodata = 0;
  EXPECT_EQ(GDALGetRasterNoDataValue(band, &has_nodata), 0.0);
  EXPECT_TRUE(has_nodata);
  GDALColorTableH table = GDALGetRasterColorTable(band);
  ASSERT_NE(table, nullptr);
  EXPECT_EQ(GDALGetColorEntry(table, 5)->c2, 150);  // vegetation is green
  EXPECT_NE(std::string(GDALGetMetadataItem(ds, "CLASS_CODES", nullptr)).find("6 building"), std::string::npos);
  EXPECT_STREQ(GDALGetMetadataItem(ds, "LAND_COVER_RULE", nullptr), "test");
  ASSERT_GE(GDALGetOverviewCount(band), 1);
  GDALRasterBandH overview = GDALGetOverview(band, 0);
  const int ox = GDALGetRasterBandXSize(overview), oy = GDALGetRasterBandYSize(overview);
  std::vector<std::uint8_t> codes(static_cast<std::size_t>(ox) * oy);
  ASSERT_EQ(GDALRasterIO(overview, GF_Read, 0, 0, ox, oy, codes.data(), ox, oy, GDT_Byte, 0, 0), CE_None);
  for (std::uint8_t c : codes) ASSERT_TRUE(c == 0 || c == 1 || c == 2 || c == 5 || c == 6) << int(c);
  GDALClose(ds);
}

}  // namespace
}  // namespace skyfall
