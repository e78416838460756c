#include "products/city_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/atomic_file.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

CityReport Finished() {
  CityReport r;
  r.city = "SYN_001";
  r.options = {{"train", {{"iterations", 1000}}}};
  r.tiles = json::array({{{"tile", "SYN_001_c0_r0"}, {"status", "ok"}}, {{"tile", "SYN_001_c1_r0"}, {"status", "degenerate"}}});
  r.aois = {"SYN_001_X0Y0", "SYN_001_X1Y0"};
  r.stages = json::array({{{"stage", "merge"}, {"status", "ok"}}});
  r.seconds = 812.5;
  r.scene = "/out/SYN_001/scene/scene.ply";
  r.dsm = json::array({{{"aoi", "SYN_001_X0Y0"}, {"mae_m", 0.875}}, {{"aoi", "SYN_001_X1Y0"}, {"mae_m", 0.9}}});
  r.products = json::array({{{"aoi", "SYN_001_X0Y0"}}});
  r.city_products = {{"ortho_city", "/out/SYN_001/ortho_city.tif"}};
  r.tiles3d = json{{"tiles", 12}};
  r.merge = {{"gaussians", 1000.0}, {"seam_line_mean_offset_m", NAN}};
  r.decisions = {{"lod_levels", {{"levels", 3}}}};
  r.seam = {{"ratio", 0.56}};
  r.peak_tile_rss_mb = 1068;
  r.inputs = {{"images", {{"a.tif", "stamp"}}}};
  return r;
}

TEST(CityReport, WhatIsWrittenIsReadBackAndWrittenAgainToTheSameBytes) {
  const fs::path dir = testing::ScratchDir("city_report");
  const std::string path = CityReportPath(dir).string();
  WriteCityReport(path, Finished());
  const std::optional<CityReport> read = ReadCityReport(path);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->city, "SYN_001");
  EXPECT_EQ(read->aois, Finished().aois);
  EXPECT_EQ(read->scene, Finished().scene);
  EXPECT_EQ(read->inputs, Finished().inputs);
  EXPECT_EQ(read->seconds, 812.5);
  EXPECT_EQ(read->peak_tile_rss_mb, 1068);
  ASSERT_TRUE(read->tiles3d);
  EXPECT_TRUE(read->merge.at("seam_line_mean_offset_m").is_null());  // a NaN is written as null and still reads
  EXPECT_FALSE(read->AnyTileFailed());  // degenerate is not failed
  EXPECT_EQ(read->DsmMaeM("SYN_001_X1Y0"), 0.9);
  EXPECT_FALSE(read->DsmMaeM("SYN_002"));
  EXPECT_EQ(read->DsmMaesM(), (std::vector<double>{0.875, 0.9}));
  const std::string first = ReadTextFile(path);
  WriteCityReport(path, *read);
  EXPECT_EQ(ReadTextFile(path), first);
}

TEST(CityReport, AFailedCityHasNoSceneAndWritesNoProducts) {
  const fs::path dir = testing::ScratchDir("city_report_failed");
  const std::string path = CityReportPath(dir).string();
  CityReport failed = Finished();
  failed.scene.reset();
  failed.tiles = json::array({{{"tile", "SYN_001_c0_r0"}, {"status", "failed"}}});
  WriteCityReport(path, failed);
  const json doc = json::parse(ReadTextFile(path));
  for (const char* key : {"scene", "dsm", "products", "inputs", "tiles3d", "merge"}) EXPECT_FALSE(doc.contains(key)) << key;
  const std::optional<CityReport> read = ReadCityReport(path);
  ASSERT_TRUE(read);
  EXPECT_FALSE(read->scene);
  EXPECT_TRUE(read->AnyTileFailed());
  EXPECT_TRUE(read->dsm.empty());
}

TEST(CityReport, MissingDamagedOrNonNumericFiguresAreSaidSo) {
  const fs::path dir = testing::ScratchDir("city_report_bad");
  const std::string path = CityReportPath(dir).string();
  EXPECT_FALSE(ReadCityReport(path));
  std::ofstream(path) << "{\"city\": \"SYN_001\", \"tiles\": [";  // cut short
  EXPECT_FALSE(ReadCityReport(path));
  std::ofstream(path, std::ios::trunc) << "{\"tiles\": []}";  // no city
  EXPECT_FALSE(ReadCityReport(path));
  CityReport r = Finished();
  r.dsm[1]["mae_m"] = nullptr;  // a comparison with no valid cell
  WriteCityReport(path, r);
  const std::optional<CityReport> read = ReadCityReport(path);
  ASSERT_TRUE(read);
  EXPECT_FALSE(read->DsmMaeM("SYN_001_X1Y0"));
  EXPECT_FALSE(read->DsmMaesM());
  r.tiles[0].erase("status");  // a tile that says nothing counts as failed
  WriteCityReport(path, r);
  ASSERT_TRUE(ReadCityReport(path));
  EXPECT_TRUE(ReadCityReport(path)->AnyTileFailed());
  // Entries of the wrong kind make the report unreadable, with the reason.
  for (const char* bad : {R"({"city": "C", "tiles": [3]})", R"({"city": "C", "tiles": [{"status": 1}]})",
                          R"({"city": "C", "tiles": [], "scene": "s.ply", "dsm": ["x"]})",
                          R"({"city": "C", "tiles": [], "scene": "s.ply", "dsm": [{"aoi": 7, "mae_m": 1}]})"}) {
    std::ofstream(path, std::ios::trunc) << bad;
    std::string why;
    EXPECT_FALSE(ReadCityReport(path, &why)) << bad;
    EXPECT_FALSE(why.empty()) << bad;
  }
}

TEST(CityReport, WritesExactlyItsKeys) {
  const fs::path dir = testing::ScratchDir("city_report_keys");
  const std::string path = CityReportPath(dir).string();
  auto keys = [&](const CityReport& r) {
    WriteCityReport(path, r);
    const json doc = json::parse(ReadTextFile(path));
    std::vector<std::string> k;
    for (const auto& [key, value] : doc.items()) k.push_back(key);
    return k;
  };
  CityReport failed = Finished();
  failed.scene.reset();
  EXPECT_EQ(keys(failed), (std::vector<std::string>{"aois", "city", "options", "seconds", "stages", "tiles"}));
  EXPECT_EQ(keys(Finished()),
            (std::vector<std::string>{"aois", "city", "city_products", "decisions", "dsm", "inputs", "merge", "options",
                                      "peak_tile_rss_mb", "products", "scene", "seam", "seconds", "stages", "tiles",
                                      "tiles3d"}));
}

}  // namespace
}  // namespace skyfall
