#include "products/point_cloud.h"

#include <gtest/gtest.h>
#include <cpl_conv.h>
#include <ogr_srs_api.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "products/point_cloud_test_support.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using testing::Bounds;
using testing::ErrorText;
using testing::TrueBounds;
using testing::Utm17nWithHeightWkt;

constexpr double kHalfStep = 0.5 * kLasScaleM;

// 1,000 points on a 50 x 20 grid with sub-millimetre coordinates, classes
// ground / high vegetation / building in turn and distinct colours.
std::vector<LasPoint> SmallCloud() {
  std::vector<LasPoint> points(1000);
  constexpr std::uint8_t kClasses[] = {2, 5, 6};
  for (int i = 0; i < 1000; ++i) {
    LasPoint& p = points[i];
    p.easting_m = 512345.67891 + (i % 50) * 0.37;
    p.northing_m = 3321000.12345 + (i / 50) * 0.53;
    p.height_m = 12.34567 + (i % 7) * 1.1;
    p.red = static_cast<std::uint16_t>((i % 256) * 257);
    p.green = static_cast<std::uint16_t>((255 - i % 256) * 257);
    p.blue = 128 * 257;
    p.classification = kClasses[i % 3];
  }
  return points;
}

TEST(PointCloud, WritesLas14Format7ThatReadsBack) {
  const fs::path file = testing::ScratchDir("las") / "cloud.las";
  const std::vector<LasPoint> points = SmallCloud();
  const std::string wkt = Utm17nWithHeightWkt();
  ASSERT_FALSE(wkt.empty());
  WriteLas(file.string(), points, wkt);

  const LasHeaderInfo info = ReadLasHeader(file.string());
  EXPECT_EQ(info.version_major, 1);
  EXPECT_EQ(info.version_minor, 4);
  EXPECT_EQ(info.point_format, 7);
  EXPECT_EQ(info.point_count, 1000u);
  const Bounds b = TrueBounds(points);
  EXPECT_NEAR(info.min_x, b.min[0], kHalfStep);
  EXPECT_NEAR(info.min_y, b.min[1], kHalfStep);
  EXPECT_NEAR(info.min_z, b.min[2], kHalfStep);
  EXPECT_NEAR(info.max_x, b.max[0], kHalfStep);
  EXPECT_NEAR(info.max_y, b.max[1], kHalfStep);
  EXPECT_NEAR(info.max_z, b.max[2], kHalfStep);
  EXPECT_EQ(info.scale_x, kLasScaleM);
  EXPECT_EQ(info.scale_y, kLasScaleM);
  EXPECT_EQ(info.scale_z, kLasScaleM);
  EXPECT_EQ(info.offset_x, 512345.0);
  EXPECT_EQ(info.offset_y, 3321000.0);
  EXPECT_EQ(info.offset_z, 12.0);
  std::array<std::uint64_t, 16> by_class{};
  by_class[2] = 334, by_class[5] = 333, by_class[6] = 333;
  EXPECT_EQ(info.points_by_class, by_class);

  // The CRS as written, and one that GDAL reads back as UTM 17N plus a height.
  EXPECT_EQ(info.crs_wkt, wkt);
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  ASSERT_EQ(OSRSetFromUserInput(srs, info.crs_wkt.c_str()), OGRERR_NONE);
  EXPECT_EQ(OSRGetAxesCount(srs), 3);
  OSRDemoteTo2D(srs, nullptr);
  ASSERT_EQ(OSRAutoIdentifyEPSG(srs), OGRERR_NONE);
  EXPECT_STREQ(OSRGetAuthorityCode(srs, nullptr), "32617");
  OSRDestroySpatialReference(srs);
}

// Header, one WKT VLR (54-byte header + the WKT and its null), 36-byte
// records, nothing else; an empty cloud is a valid file with zero bounds.
TEST(PointCloud, FileIsHeaderVlrAndRecords) {
  const fs::path dir = testing::ScratchDir("las");
  const std::string wkt = Utm17nWithHeightWkt();
  WriteLas((dir / "cloud.las").string(), SmallCloud(), wkt);
  EXPECT_EQ(fs::file_size(dir / "cloud.las"), 375 + 54 + wkt.size() + 1 + 36 * 1000);

  WriteLas((dir / "empty.las").string(), {}, wkt);
  EXPECT_EQ(fs::file_size(dir / "empty.las"), 375 + 54 + wkt.size() + 1);
  const LasHeaderInfo empty = ReadLasHeader((dir / "empty.las").string());
  EXPECT_EQ(empty.point_count, 0u);
  EXPECT_EQ(empty.min_x, 0.0);
  EXPECT_EQ(empty.max_z, 0.0);
  EXPECT_EQ(empty.crs_wkt, wkt);
}

TEST(PointCloud, ReaderRefusesNonLasAndTruncatedFilesNamingThePath) {
  const fs::path dir = testing::ScratchDir("las");
  const std::string text = (dir / "notes.las").string();
  std::ofstream(text) << "not a point cloud\n";
  const std::string not_las = ErrorText([&] { ReadLasHeader(text); });
  EXPECT_NE(not_las.find(text), std::string::npos) << not_las;
  EXPECT_NE(not_las.find("LASF"), std::string::npos) << not_las;

  const std::string cut = (dir / "cut.las").string();
  WriteLas(cut, SmallCloud(), Utm17nWithHeightWkt());
  fs::resize_file(cut, fs::file_size(cut) - 10);  // the last record loses its colour
  const std::string truncated = ErrorText([&] { ReadLasHeader(cut); });
  EXPECT_NE(truncated.find(cut), std::string::npos) << truncated;
  EXPECT_NE(truncated.find("truncated"), std::string::npos) << truncated;

  fs::resize_file(cut, 200);  // inside the header
  EXPECT_NE(ErrorText([&] { ReadLasHeader(cut); }).find("truncated"), std::string::npos);
}

TEST(PointCloud, WriterRefusesNonFiniteCoordinatesAndNoCrs) {
  const fs::path dir = testing::ScratchDir("las");
  const std::string file = (dir / "bad.las").string();
  std::vector<LasPoint> points = SmallCloud();
  points[7].height_m = std::nan("");
  const std::string nan = ErrorText([&] { WriteLas(file, points, Utm17nWithHeightWkt()); });
  EXPECT_NE(nan.find(file), std::string::npos) << nan;
  EXPECT_NE(nan.find("point 7"), std::string::npos) << nan;

  const std::string no_crs = ErrorText([&] { WriteLas(file, SmallCloud(), ""); });
  EXPECT_NE(no_crs.find(file), std::string::npos) << no_crs;
  EXPECT_NE(no_crs.find("CRS"), std::string::npos) << no_crs;
  EXPECT_FALSE(fs::exists(file));
}

// loaders.gl's LAS loader (web/check_las.mjs), a reader that is not ours,
// finds the count, bounds, scale and offset written, and the same classes.
TEST(PointCloud, IndependentReaderAgrees) {
  const fs::path web = fs::path(SKYFALL_SOURCE_DIR) / "web";
  if (!fs::exists(web / "node_modules" / "@loaders.gl" / "las")) {
    GTEST_SKIP() << "no @loaders.gl/las in " << web << "/node_modules (run npm ci in web/)";
  }
  const fs::path dir = testing::ScratchDir("las");
  if (testing::RunCommand("node --version", dir).exit_code != 0) GTEST_SKIP() << "node is not on the PATH";
  const fs::path file = dir / "cloud.las";
  const std::vector<LasPoint> points = SmallCloud();
  WriteLas(file.string(), points, Utm17nWithHeightWkt());

  const testing::CommandResult checked =
      testing::RunCommand("node " + (web / "check_las.mjs").string() + " " + file.string(), dir);
  ASSERT_EQ(checked.exit_code, 0) << checked.err;
  const auto loaded = nlohmann::json::parse(checked.out);
  EXPECT_EQ(loaded["count"].get<std::uint64_t>(), points.size());
  const Bounds b = TrueBounds(points);
  const double offsets[3] = {512345.0, 3321000.0, 12.0};
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(loaded["mins"][a].get<double>(), b.min[a], kHalfStep) << "axis " << a;
    EXPECT_NEAR(loaded["maxs"][a].get<double>(), b.max[a], kHalfStep) << "axis " << a;
    EXPECT_EQ(loaded["scale"][a].get<double>(), kLasScaleM) << "axis " << a;
    EXPECT_EQ(loaded["offset"][a].get<double>(), offsets[a]) << "axis " << a;
  }
  EXPECT_EQ(loaded["classes"], nlohmann::json({{"2", 334}, {"5", 333}, {"6", 333}}));
}

}  // namespace
}  // namespace skyfall
