#include "products/dsm_breakdown.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>

#include "core/error.h"
#include "products/dsm.h"
#include "products/dsm_report.h"
#include "tests/test_support.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

constexpr int kW = 20, kH = 16;
constexpr double kGsdM = 0.5;
constexpr double kSumTolM = 1e-9;  // sums of a few hundred doubles

// A 6 x 6-cell building (class 6) at columns 7-12, rows 5-10, one tree cell
// (class 5) and ground (class 2) elsewhere.
std::vector<float> ToyClasses() {
  std::vector<float> cls(kW * kH, 2.0f);
  for (int r = 5; r <= 10; ++r)
    for (int c = 7; c <= 12; ++c) cls[r * kW + c] = 6.0f;
  cls[2 * kW + 2] = 5.0f;
  return cls;
}

bool InBuilding(int c, int r) { return c >= 7 && c <= 12 && r >= 5 && r <= 10; }

// Brute force: the smallest centre-to-centre distance [cells] from (c, r) to a
// cell on the other side of the building outline.
double DistanceAcross(int c, int r) {
  double best = std::numeric_limits<double>::infinity();
  for (int rr = 0; rr < kH; ++rr)
    for (int cc = 0; cc < kW; ++cc)
      if (InBuilding(cc, rr) != InBuilding(c, r)) best = std::min(best, std::hypot(cc - c, rr - r));
  return best;
}

TEST(DsmBreakdown, ClassFiguresAndRimBandsMatchABruteForceCount) {
  const std::vector<float> cls = ToyClasses();
  std::vector<float> error(kW * kH);
  for (int p = 0; p < kW * kH; ++p) error[p] = 0.01f * static_cast<float>((p * 37) % 23) - 0.1f;
  error[0] = NAN;  // not compared: left out of every group
  const DsmBreakdown b = BreakDownDsmError(error, cls, kW, kH, kGsdM, DsmBreakdownOptions{});

  ASSERT_EQ(b.classes.size(), 3u);
  EXPECT_EQ(b.classes[0].name, "ground");
  EXPECT_EQ(b.classes[1].name, "high_vegetation");
  EXPECT_EQ(b.classes[2].name, "building");
  EXPECT_EQ(b.classes[2].cells, 36);
  EXPECT_EQ(b.classes[1].cells, 1);
  EXPECT_EQ(b.classes[0].cells, kW * kH - 36 - 1 - 1);

  // Each class against a direct computation; the parts add up to the MAE.
  double part_sum = 0, abs_all = 0;
  int compared = 0;
  for (float e : error)
    if (std::isfinite(e)) abs_all += std::abs(e), ++compared;
  for (const DsmErrorGroup& g : b.classes) {
    double abs_sum = 0, sum = 0, sq = 0;
    int n = 0;
    for (int p = 0; p < kW * kH; ++p) {
      if (!std::isfinite(error[p]) || static_cast<int>(cls[p]) != g.cls) continue;
      abs_sum += std::abs(error[p]), sum += error[p], sq += error[p] * error[p], ++n;
    }
    EXPECT_EQ(g.cells, n) << g.name;
    EXPECT_NEAR(g.mae_m, abs_sum / n, kSumTolM) << g.name;
    EXPECT_NEAR(g.bias_m, sum / n, kSumTolM) << g.name;
    EXPECT_NEAR(g.rmse_m, std::sqrt(sq / n), kSumTolM) << g.name;
    EXPECT_NEAR(g.share, static_cast<double>(n) / compared, kSumTolM) << g.name;
    part_sum += g.mae_part_m;
  }
  EXPECT_NEAR(part_sum, abs_all / compared, kSumTolM);

  // Every cell but the tree (the "vegetation masked" protocol): its MAE is
  // the MAE less the tree's part, over the cells that are left.
  double abs_without = 0;
  int without = 0;
  for (int p = 0; p < kW * kH; ++p) {
    if (!std::isfinite(error[p]) || static_cast<int>(cls[p]) == 5) continue;
    abs_without += std::abs(error[p]), ++without;
  }
  EXPECT_EQ(b.without_high_vegetation.name, "without_high_vegetation");
  EXPECT_EQ(b.without_high_vegetation.cells, compared - 1);
  EXPECT_EQ(b.without_high_vegetation.cells, without);
  EXPECT_NEAR(b.without_high_vegetation.mae_m, abs_without / without, kSumTolM);
  EXPECT_NEAR(b.without_high_vegetation.mae_m * without,
              (abs_all / compared - b.classes[1].mae_part_m) * compared, 1e-6);

  // Rim width 1 m = 2 cells at 0.5 m.
  int roof_rim = 0, beside = 0;
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c) {
      if (!std::isfinite(error[r * kW + c]) || DistanceAcross(c, r) > 2.0) continue;
      (InBuilding(c, r) ? roof_rim : beside) += 1;
    }
  EXPECT_EQ(roof_rim, 36 - 4);  // all but the 2 x 2 core
  EXPECT_EQ(b.roof_rim.cells, roof_rim);
  EXPECT_EQ(b.beside_buildings.cells, beside);
  EXPECT_EQ(b.roof_rim.cls, -1);
}

TEST(DsmBreakdown, RimErrorsShowApartFromTheRestOfTheirClass) {
  // A roof one cell too wide on every side (the fattening of a DSM at steps):
  // the first ring of ground around the building is 30 m too high.
  const std::vector<float> cls = ToyClasses();
  std::vector<float> error(kW * kH, 0.0f);
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c)
      if (!InBuilding(c, r) && DistanceAcross(c, r) < 1.5) error[r * kW + c] = 30.0f;
  const DsmBreakdown b = BreakDownDsmError(error, cls, kW, kH, kGsdM, DsmBreakdownOptions{});
  EXPECT_NEAR(b.roof_rim.mae_m, 0.0, kSumTolM);
  EXPECT_GT(b.beside_buildings.bias_m, 10.0);
  EXPECT_NEAR(b.beside_buildings.mae_part_m, b.classes[0].mae_part_m, kSumTolM);  // all the ground's error
  EXPECT_NEAR(b.classes[2].mae_m, 0.0, kSumTolM);
}

TEST(DsmBreakdown, EdgeBandsMatchABruteForceCount) {
  // Band k holds the cells more than k and at most k + 1 band widths from
  // the nearest cell across the outline (in metres: distances in cells times
  // the GSD); the roof's cells beyond the last band are its interior. Band
  // widths of one cell, two cells and one and a half.
  const std::vector<float> cls = ToyClasses();
  std::vector<float> error(kW * kH);
  for (int p = 0; p < kW * kH; ++p) error[p] = 0.02f * static_cast<float>((p * 29) % 17) - 0.15f;
  error[5 * kW + 7] = NAN;  // a roof corner and the ground beside it, both in band 0: left out
  error[4 * kW + 7] = NAN;
  for (const double band_m : {0.5, 1.0, 0.75}) {
    DsmBreakdownOptions o;
    o.edge_band_m = band_m;
    o.edge_bands = 2;
    const DsmBreakdown b = BreakDownDsmError(error, cls, kW, kH, kGsdM, o);
    ASSERT_EQ(b.roof_bands.size(), 2u);
    ASSERT_EQ(b.beside_bands.size(), 2u);
    EXPECT_EQ(b.edge_band_m, band_m);
    for (const bool roof : {true, false}) {
      for (int k = 0; k <= 2; ++k) {
        if (k == 2 && !roof) continue;  // beside the buildings there is no interior
        int n = 0;
        double sum = 0;
        for (int r = 0; r < kH; ++r)
          for (int c = 0; c < kW; ++c) {
            const float e = error[r * kW + c];
            if (!std::isfinite(e) || InBuilding(c, r) != roof) continue;
            const double d_m = DistanceAcross(c, r) * kGsdM;
            constexpr double kTol = 1e-9;
            const bool in_band = k < 2 ? d_m > k * band_m + kTol && d_m <= (k + 1) * band_m + kTol
                                       : d_m > 2 * band_m + kTol;
            if (in_band) ++n, sum += e;
          }
        const DsmErrorGroup& g = k < 2 ? (roof ? b.roof_bands[k] : b.beside_bands[k]) : b.roof_interior;
        EXPECT_EQ(g.cells, n) << g.name << " at " << band_m << " m";
        if (n > 0) EXPECT_NEAR(g.bias_m, sum / n, kSumTolM) << g.name;
      }
    }
  }
  // One-cell bands on the 6 x 6 roof: its outer ring (20 cells, one its NaN
  // corner) at 0.5 m from the ground, the next ring (12) at 1 m, the 2 x 2
  // core beyond. With the defaults the rim band (1 m) is the first two bands.
  const DsmBreakdown b = BreakDownDsmError(error, cls, kW, kH, kGsdM, DsmBreakdownOptions{});
  EXPECT_EQ(b.roof_bands[0].cells, 19);
  EXPECT_EQ(b.roof_bands[0].name, "roof_band_0");
  EXPECT_EQ(b.roof_bands[1].cells, 12);
  EXPECT_EQ(b.roof_bands[2].cells, 4);
  EXPECT_EQ(b.roof_interior.cells, 0);
  EXPECT_EQ(b.roof_interior.name, "roof_interior");
  EXPECT_EQ(b.roof_rim.cells, b.roof_bands[0].cells + b.roof_bands[1].cells);
  EXPECT_EQ(b.beside_buildings.cells, b.beside_bands[0].cells + b.beside_bands[1].cells);
}

TEST(DsmBreakdown, AComparisonWithoutClassesLeavesNoEarlierBreakdownBehind) {
  DsmGrid truth;
  truth.width_px = kW;
  truth.height_px = kH;
  truth.gsd_m = kGsdM;
  truth.epsg = 32617;
  truth.upper_left_easting_m = 435000;
  truth.upper_left_northing_m = 3350000;
  const std::vector<float> cls = ToyClasses();
  for (int p = 0; p < kW * kH; ++p) truth.height_m.push_back(10.0f + 0.01f * p + (cls[p] == 6.0f ? 10.0f : 0.0f));
  const fs::path dir = ScratchDir("breakdown_stale");
  WriteDsmComparison(CompareDsm(truth, truth, &cls, DsmCompareOptions{}), truth, DsmCompareOptions{}, {}, dir.string());
  ASSERT_TRUE(fs::exists(dir / "report_by_class.csv"));
  ASSERT_TRUE(fs::exists(dir / "report_edge_profile.csv"));
  WriteDsmComparison(CompareDsm(truth, truth, nullptr, DsmCompareOptions{}), truth, DsmCompareOptions{}, {}, dir.string());
  EXPECT_FALSE(fs::exists(dir / "report_by_class.csv"));
  EXPECT_FALSE(fs::exists(dir / "report_edge_profile.csv"));
  EXPECT_TRUE(fs::exists(dir / "report.json"));
}

TEST(DsmBreakdown, AGridOfBuildingIsAllInterior) {
  // Nothing across an outline: no band, every roof cell in the interior.
  const std::vector<float> cls(kW * kH, 6.0f), error(kW * kH, 0.5f);
  const DsmBreakdown b = BreakDownDsmError(error, cls, kW, kH, kGsdM, DsmBreakdownOptions{});
  EXPECT_EQ(b.roof_interior.cells, kW * kH);
  for (const DsmErrorGroup& g : b.roof_bands) EXPECT_EQ(g.cells, 0) << g.name;
  for (const DsmErrorGroup& g : b.beside_bands) EXPECT_EQ(g.cells, 0) << g.name;
}

TEST(DsmBreakdown, AnErodedRoofShowsInItsFirstBandOnly) {
  // The roof's outermost ring 20 m too low (an edge eroded by one cell): the
  // first roof band carries all of it, the next bands and the ground nothing.
  const std::vector<float> cls = ToyClasses();
  std::vector<float> error(kW * kH, 0.0f);
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c)
      if (InBuilding(c, r) && DistanceAcross(c, r) < 1.5) error[r * kW + c] = -20.0f;
  const DsmBreakdown b = BreakDownDsmError(error, cls, kW, kH, kGsdM, DsmBreakdownOptions{});
  EXPECT_NEAR(b.roof_bands[0].bias_m, -20.0, kSumTolM);
  EXPECT_NEAR(b.roof_bands[0].mae_part_m, b.classes[2].mae_part_m, kSumTolM);
  for (std::size_t k = 1; k < b.roof_bands.size(); ++k) EXPECT_NEAR(b.roof_bands[k].mae_m, 0.0, kSumTolM);
  for (const DsmErrorGroup& g : b.beside_bands) EXPECT_NEAR(g.mae_m, 0.0, kSumTolM) << g.name;
}

TEST(DsmBreakdown, NoBuildingsLeavesTheRimBandsEmpty) {
  const std::vector<float> cls(kW * kH, 2.0f), error(kW * kH, 0.25f);
  const DsmBreakdown b = BreakDownDsmError(error, cls, kW, kH, kGsdM, DsmBreakdownOptions{});
  ASSERT_EQ(b.classes.size(), 1u);
  EXPECT_NEAR(b.classes[0].mae_m, 0.25, 1e-7);
  EXPECT_EQ(b.roof_rim.cells, 0);
  EXPECT_EQ(b.beside_buildings.cells, 0);
  for (const DsmErrorGroup& g : b.roof_bands) EXPECT_EQ(g.cells, 0) << g.name;
  for (const DsmErrorGroup& g : b.beside_bands) EXPECT_EQ(g.cells, 0) << g.name;
  EXPECT_EQ(b.roof_interior.cells, 0);
}

TEST(DsmBreakdown, BadInputIsRefused) {
  const std::vector<float> cls = ToyClasses(), error(kW * kH, 0.0f);
  EXPECT_THROW(BreakDownDsmError(error, std::vector<float>(10, 2.0f), kW, kH, kGsdM, DsmBreakdownOptions{}), Error);
  EXPECT_THROW(BreakDownDsmError(error, cls, kW, kH, 0.0, DsmBreakdownOptions{}), Error);
  DsmBreakdownOptions bad;
  bad.rim_width_m = 0;
  EXPECT_THROW(BreakDownDsmError(error, cls, kW, kH, kGsdM, bad), Error);
  bad = DsmBreakdownOptions{};
  bad.edge_band_m = -0.5;
  EXPECT_THROW(BreakDownDsmError(error, cls, kW, kH, kGsdM, bad), Error);
  bad.edge_band_m = std::numeric_limits<double>::infinity();
  EXPECT_THROW(BreakDownDsmError(error, cls, kW, kH, kGsdM, bad), Error);
  bad = DsmBreakdownOptions{};
  bad.edge_bands = 0;
  EXPECT_THROW(BreakDownDsmError(error, cls, kW, kH, kGsdM, bad), Error);
  EXPECT_EQ(AsprsClassName(64), "class_64");
}

TEST(DsmBreakdown, CellsWithoutAClassFormTheirOwnGroup) {
  // A user's float class raster may hold NaN (nodata) or values that are no
  // class code: they are grouped apart, and the parts still add up.
  std::vector<float> cls = ToyClasses(), error(kW * kH, 1.0f);
  cls[0] = NAN;
  cls[1] = -3.0f;
  cls[2] = 1e9f;
  const DsmBreakdown b = BreakDownDsmError(error, cls, kW, kH, kGsdM, DsmBreakdownOptions{});
  ASSERT_EQ(b.classes.front().name, "no_class");
  EXPECT_EQ(b.classes.front().cells, 3);
  double parts = 0;
  for (const DsmErrorGroup& g : b.classes) parts += g.mae_part_m;
  EXPECT_NEAR(parts, 1.0, kSumTolM);
  EXPECT_EQ(ClassCodeOf(5.9999f), 6);  // a resampled raster's near-integers round
  EXPECT_EQ(ClassCodeOf(NAN), -1);
}

TEST(DsmBreakdown, NothingComparedStillNamesItsGroups) {
  const std::vector<float> cls = ToyClasses(), error(kW * kH, NAN);
  const DsmBreakdown b = BreakDownDsmError(error, cls, kW, kH, kGsdM, DsmBreakdownOptions{});
  EXPECT_TRUE(b.classes.empty());
  EXPECT_EQ(b.roof_rim.name, "roof_rim");
  EXPECT_EQ(b.roof_rim.cells, 0);
  EXPECT_EQ(b.beside_buildings.name, "beside_buildings");
}

TEST(DsmBreakdown, AClassRasterOfAnotherSizeIsRefusedByName) {
  const fs::path dir = ScratchDir("cls_size");
  const std::vector<float> values(8 * 6, 2.0f);
  const std::string path = (dir / "AOI_CLS.tif").string();
  WriteFloatTiff(path, 8, 6, values.data());
  DsmGrid truth;
  truth.width_px = 6;
  truth.height_px = 8;
  try {
    ReadClassRaster(path, truth);
    FAIL() << "a transposed class raster was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("AOI_CLS.tif"), std::string::npos) << e.what();
  }
  truth.width_px = 8;
  truth.height_px = 6;
  EXPECT_EQ(ReadClassRaster(path, truth).size(), values.size());
}

TEST(DsmBreakdown, JaxComparisonReportsItsClasses) {
  SKYFALL_REQUIRE_DFC2019();
  const fs::path t = Dfc2019Root() / "Track3-Truth";
  const DsmGrid truth = ReadDsm((t / "JAX_068_DSM.tif").string(), (t / "JAX_068_DSM.txt").string(), 32617);
  const std::vector<float> cls = ReadFloatBand((t / "JAX_068_CLS.tif").string()).values;
  DsmGrid pred = truth;
  for (float& h : pred.height_m) h += 0.3f;  // removed by the vertical offset
  for (std::size_t p = 0; p < cls.size(); p += 7) {
    if (static_cast<int>(cls[p]) == 6) pred.height_m[p] += 5.0f;  // some roof cells wrong
  }
  const DsmComparison r = CompareDsm(pred, truth, &cls, DsmCompareOptions{});
  ASSERT_TRUE(r.has_breakdown);
  double part_sum = 0;
  for (const DsmErrorGroup& g : r.breakdown.classes) {
    part_sum += g.mae_part_m;
    if (g.name != "building") {
      EXPECT_LT(g.mae_m, 1e-5) << g.name;
    }
  }
  EXPECT_NEAR(part_sum, r.mae_m, 1e-6);
  const fs::path dir = ScratchDir("breakdown_report");
  WriteDsmComparison(r, truth, DsmCompareOptions{}, {"p.tif", "t.tif", "c.tif"}, dir.string());
  const nlohmann::json report = nlohmann::json::parse(std::ifstream(dir / "report.json"));
  ASSERT_TRUE(report.contains("by_class"));
  // One group per class present among the compared cells, counted here from
  // the raster itself.
  std::set<int> present;
  for (std::size_t p = 0; p < cls.size(); ++p)
    if (std::isfinite(r.error_m[p])) present.insert(static_cast<int>(cls[p]));
  EXPECT_EQ(report["by_class"].size(), present.size());
  EXPECT_EQ(report["building_rims"]["roof_rim"]["cells"], r.breakdown.roof_rim.cells);
  EXPECT_GT(r.breakdown.roof_rim.cells, 0);
  // The CSV's columns as docs/outputs.md gives them, one row per group.
  std::ifstream csv(dir / "report_by_class.csv");
  std::string header, line;
  std::getline(csv, header);
  EXPECT_EQ(header, "group,class,cells,share,mae_m,rmse_m,median_abs_m,bias_m,mae_part_m");
  std::size_t rows = 0;
  while (std::getline(csv, line)) ++rows;
  EXPECT_EQ(rows, present.size() + 3);  // and the rims, and every class but high vegetation
  // The edge profile: JSON bands with their bounds, and the CSV's rows
  // (roof bands, roof interior, bands beside).
  // Every building cell is in one roof band or the interior.
  const nlohmann::json& profile = report["building_edge_profile"];
  ASSERT_EQ(profile["roof"].size(), 6u);
  ASSERT_EQ(profile["beside"].size(), 6u);
  int roof_cells = profile["roof_interior"]["cells"].get<int>();
  for (const auto& band : profile["roof"]) roof_cells += band["cells"].get<int>();
  int building_cells = 0;
  for (const auto& g : report["by_class"])
    if (g["name"] == "building") building_cells = g["cells"].get<int>();
  EXPECT_GT(profile["roof"][0]["cells"].get<int>(), 0);
  EXPECT_EQ(roof_cells, building_cells);
  EXPECT_DOUBLE_EQ(profile["band_m"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(profile["roof"][1]["from_m"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(profile["beside"][5]["to_m"].get<double>(), 3.0);
  EXPECT_DOUBLE_EQ(profile["roof_interior"]["from_m"].get<double>(), 3.0);
  EXPECT_FALSE(profile["roof_interior"].contains("to_m"));
  // The CSV: the roof's bands inwards, its interior (no upper bound), the
  // bands beside outwards.
  std::ifstream edge_csv(dir / "report_edge_profile.csv");
  std::getline(edge_csv, header);
  EXPECT_EQ(header, "side,from_m,to_m,cells,share,mae_m,rmse_m,median_abs_m,bias_m,mae_part_m");
  std::vector<std::string> bounds;
  while (std::getline(edge_csv, line)) bounds.push_back(line.substr(0, line.find(',', line.find(',', line.find(',') + 1) + 1)));
  const std::vector<std::string> expected = {"roof,0,0.5",   "roof,0.5,1",   "roof,1,1.5",   "roof,1.5,2",   "roof,2,2.5",
                                             "roof,2.5,3",   "roof,3,",      "beside,0,0.5", "beside,0.5,1", "beside,1,1.5",
                                             "beside,1.5,2", "beside,2,2.5", "beside,2.5,3"};
  EXPECT_EQ(bounds, expected);
}

}  // namespace
}  // namespace skyfall
