#include "ingest/dfc2019.h"

#include <gtest/gtest.h>

#include <fstream>

#include "catalogs/aoi_catalog.h"
#include "core/error.h"
#include "tests/test_support.h"
#include "ingest/geo.h"
#include "ingest/rpc_io.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

TEST(DsmTxt, ParsesTheDfc2019Layout) {
  const DsmTxt d = ParseDsmTxt("436078.995946\n3357495.999923\n512.000000\n0.500000\n", "a_DSM.txt");
  EXPECT_DOUBLE_EQ(d.easting_m, 436078.995946);
  EXPECT_DOUBLE_EQ(d.northing_m, 3357495.999923);
  EXPECT_EQ(d.size_px, 512);
  EXPECT_DOUBLE_EQ(d.gsd_m, 0.5);
}

TEST(DsmTxt, MalformedFieldsAreNamed) {
  struct Case {
    const char* text;
    const char* expected;
  };
  const Case cases[] = {
      {"436078.9\n3357495.9\n512\n", "found 3 (first problem: gsd)"},
      {"436078.9\nabc\n512\n0.5\n", "a_DSM.txt: northing: is not a finite number: 'abc'"},
      {"436078.9\n3357495.9\n512.5\n0.5\n", "a_DSM.txt: size: 512.5 is not a positive pixel count"},
      {"436078.9\n3357495.9\n512\n-0.5\n", "a_DSM.txt: gsd: -0.5 must be > 0"},
      {"nan\n3357495.9\n512\n0.5\n", "a_DSM.txt: easting: is not a finite number"},
      {"4360780.9\n3357495.9\n512\n0.5\n", "a_DSM.txt: easting: 4360780.9 is not a UTM easting"},
      {"", "found 0 (first problem: easting)"},
  };
  for (const Case& c : cases) {
    const std::string msg = ErrorText([&] { ParseDsmTxt(c.text, "a_DSM.txt"); });
    EXPECT_NE(msg.find(c.expected), std::string::npos) << "got: " << msg;
  }
}

TEST(IngestOptions, CheckNamesTheBadField) {
  IngestOptions o;
  o.height_margin_m = -1;
  EXPECT_NE(ErrorText([&] { o.Check(); }).find("height_margin_m"), std::string::npos);
}

class IngestJax068 : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(Dfc2019Root() / "Track3-Truth")) GTEST_SKIP() << "no shared data";
    out_dir_ = ScratchDir("out");
    NullProgress progress;
    result_ = RunIngest(IngestOptions{}, Dfc2019Root().string(), out_dir_.string(), progress);
  }
  fs::path out_dir_;
  IngestResult result_;
};

TEST_F(IngestJax068, WritesACompleteCatalog) {
  ASSERT_EQ(result_.aois.size(), 1u);
  EXPECT_EQ(result_.NumIngested(), 1);
  const AoiCatalog c = ReadAoiCatalog((out_dir_ / "JAX_068" / "aoi.json").string());
  EXPECT_EQ(c.aoi, "JAX_068");
  ASSERT_EQ(c.images.size(), 19u);
  EXPECT_EQ(c.epsg, 32617);  // DFC2019 truth: UTM 17N
  EXPECT_EQ(c.train_images.size(), 17u);
  EXPECT_EQ(c.test_images, (std::vector<std::string>{"JAX_068_002_RGB", "JAX_068_012_RGB"}));
  for (const ImageRecord& im : c.images) {
    EXPECT_EQ(im.bands, 3);
    EXPECT_EQ(im.dtype, "Byte");
    EXPECT_EQ(im.rpc_source, "gdal_metadata");
    EXPECT_EQ(im.acquisition_time.size(), 20u) << im.name;  // from NITF_IDATIM
    EXPECT_TRUE(im.sun_elevation_deg && im.sun_azimuth_deg) << im.name;  // from the JSONs
    // WorldView-3 collects within ~35 deg off-nadir; the off-nadir angle at the
    // satellite is smaller than the incidence angle at the ground.
    EXPECT_GT(im.off_nadir_deg, 0.0);
    EXPECT_LT(im.off_nadir_deg, 35.0);
    EXPECT_LT(im.off_nadir_deg, im.view_zenith_deg);
    EXPECT_GE(im.view_azimuth_deg, 0.0);
    EXPECT_LT(im.view_azimuth_deg, 360.0);
    EXPECT_EQ(im.footprint_lonlat.size(), 4u);
    EXPECT_TRUE(fs::path(im.path).is_absolute());
  }
  const ImageRecord& first = c.images.front();
  EXPECT_EQ(first.name, "JAX_068_001_RGB");
  EXPECT_EQ(first.acquisition_time, "2014-10-05T16:01:38Z");
  EXPECT_EQ(first.width_px, 746);
  EXPECT_EQ(first.height_px, 815);
}

TEST_F(IngestJax068, TruthGridUsesTheLowerLeftConvention) {
  const AoiCatalog& c = result_.aois.at(0).catalog;
  ASSERT_TRUE(c.truth.has_value());
  const TruthGrid& t = *c.truth;
  EXPECT_DOUBLE_EQ(t.lower_left_easting_m, 436078.995946);
  EXPECT_DOUBLE_EQ(t.lower_left_northing_m, 3357495.999923);
  EXPECT_DOUBLE_EQ(t.UpperLeftNorthing(), 3357495.999923 + 512 * 0.5);
  EXPECT_EQ(t.width_px, 512);
  EXPECT_DOUBLE_EQ(t.gsd_m, 0.5);
  EXPECT_EQ(t.epsg, 32617);
  EXPECT_FALSE(t.cls_path.empty());
  // The DSM's own statistics (stored in its .aux.xml by GDAL): -26.30 .. 29.22 m.
  EXPECT_NEAR(t.min_height_m, -26.2958, 1e-3);
  EXPECT_NEAR(t.max_height_m, 29.2188, 1e-3);
  EXPECT_EQ(c.height_range_source, "truth_dsm");
  EXPECT_NEAR(c.min_ellipsoid_height_m, t.min_height_m - 5.0, 1e-9);

  // The footprint is the truth grid: its corners map back to the grid corners.
  ASSERT_EQ(c.footprint_source, "truth_grid");
  const UtmZone zone = UtmZoneFromEpsg(c.epsg);
  const Eigen::Vector2d ll = UtmFromGeodetic(zone, c.footprint_lonlat[0].x(), c.footprint_lonlat[0].y());
  EXPECT_NEAR(ll.x(), t.lower_left_easting_m, 1e-6);
  EXPECT_NEAR(ll.y(), t.lower_left_northing_m, 1e-6);
  const Eigen::Vector2d ur = UtmFromGeodetic(zone, c.footprint_lonlat[2].x(), c.footprint_lonlat[2].y());
  EXPECT_NEAR(ur.y(), t.UpperLeftNorthing(), 1e-6);

  // The ENU origin is the grid centre, and every image sees it.
  const Eigen::Vector2d centre = UtmFromGeodetic(zone, c.enu_origin.lon_deg, c.enu_origin.lat_deg);
  EXPECT_NEAR(centre.x(), t.lower_left_easting_m + 128.0, 1e-6);
  EXPECT_NEAR(centre.y(), t.lower_left_northing_m + 128.0, 1e-6);
  for (const ImageRecord& im : c.images) {
    const Eigen::Vector2d px = im.rpc.Project(c.enu_origin.lon_deg, c.enu_origin.lat_deg, c.enu_origin.height_m);
    EXPECT_GT(px.x(), 0);
    EXPECT_LT(px.x(), im.width_px);
    EXPECT_GT(px.y(), 0);
    EXPECT_LT(px.y(), im.height_px);
  }
}

// A DFC2019-like tree made of links to the real files plus broken ones.
class IngestBadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(Dfc2019Root() / "Track3-Truth")) GTEST_SKIP() << "no shared data";
    root_ = ScratchDir("ingest_bad") / "root";
    crops_ = root_ / "Track3-RGB-crops";
    truth_ = root_ / "Track3-Truth";
    fs::create_directories(truth_);
  }
  void LinkImage(const std::string& aoi, const std::string& nnn, const std::string& real_nnn) {
    fs::create_directories(crops_ / aoi);
    fs::create_symlink(Jax068Image(real_nnn), crops_ / aoi / (aoi + "_" + nnn + "_RGB.tif"));
  }
  void WriteFile(const fs::path& p, const std::string& text) {
    fs::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
  }
  IngestResult Run(const IngestOptions& options = {}) {
    NullProgress progress;
    return RunIngest(options, root_.string(), (root_.parent_path() / "out").string(), progress);
  }
  static const AoiIngestResult& Find(const IngestResult& r, const std::string& aoi) {
    for (const auto& a : r.aois)
      if (a.aoi == aoi) return a;
    throw std::runtime_error("no result for " + aoi);
  }
  fs::path root_, crops_, truth_;
};

TEST_F(IngestBadInput, BadImagesAreSkippedAndBadAoisDoNotStopTheOthers) {
  // GOOD_001: two good images, one corrupt, one without RPC.
  LinkImage("GOOD_001", "001", "001");
  LinkImage("GOOD_001", "002", "002");
  WriteFile(crops_ / "GOOD_001" / "GOOD_001_003_RGB.tif", "this is not a tiff");
  WriteTestRaster(crops_ / "GOOD_001" / "GOOD_001_004_RGB.tif", "GTiff", 16, 16, 3);
  // BAD_002: only a corrupt image.
  WriteFile(crops_ / "BAD_002" / "BAD_002_001_RGB.tif", "II*");
  // TXT_003: good images but a malformed truth grid file.
  LinkImage("TXT_003", "001", "005");
  fs::create_symlink(Dfc2019Root() / "Track3-Truth" / "JAX_068_DSM.tif", truth_ / "TXT_003_DSM.tif");
  WriteFile(truth_ / "TXT_003_DSM.txt", "436078.995946\n3357495.999923\nfive-twelve\n0.5\n");

  const IngestResult r = Run();
  EXPECT_EQ(r.NumIngested(), 1);
  const AoiIngestResult& good = Find(r, "GOOD_001");
  EXPECT_EQ(good.report.status, StageStatus::kOk);
  EXPECT_EQ(good.catalog.images.size(), 2u);
  ASSERT_EQ(good.skipped_images.size(), 2u);
  EXPECT_NE(good.skipped_images[0].reason.find("GOOD_001_003_RGB.tif: not a readable raster"),
            std::string::npos) << good.skipped_images[0].reason;
  EXPECT_NE(good.skipped_images[1].reason.find("GOOD_001_004_RGB.tif: no RPC metadata"),
            std::string::npos) << good.skipped_images[1].reason;
  EXPECT_TRUE(fs::exists(good.catalog_path));
  // Without truth or JSONs the height range comes from the RPC, and the
  // footprint from the images.
  EXPECT_EQ(good.catalog.height_range_source, "rpc");
  EXPECT_EQ(good.catalog.footprint_source, "image_overlap");

  const AoiIngestResult& bad = Find(r, "BAD_002");
  EXPECT_EQ(bad.report.status, StageStatus::kFailed);
  EXPECT_NE(bad.report.message.find("no usable image"), std::string::npos);
  EXPECT_FALSE(fs::exists(root_.parent_path() / "out" / "BAD_002" / "aoi.json"));

  const AoiIngestResult& txt = Find(r, "TXT_003");
  EXPECT_EQ(txt.report.status, StageStatus::kFailed);
  EXPECT_NE(txt.report.message.find("TXT_003_DSM.txt: size: is not a finite number: 'five-twelve'"),
            std::string::npos) << txt.report.message;
}

TEST_F(IngestBadInput, GridSizeDisagreeingWithTheDsmIsReported) {
  LinkImage("SIZE_001", "001", "001");
  fs::create_symlink(Dfc2019Root() / "Track3-Truth" / "JAX_068_DSM.tif", truth_ / "SIZE_001_DSM.tif");
  WriteFile(truth_ / "SIZE_001_DSM.txt", "436078.995946\n3357495.999923\n256\n0.5\n");
  const IngestResult r = Run();
  EXPECT_EQ(r.NumIngested(), 0);
  EXPECT_NE(Find(r, "SIZE_001").report.message.find("SIZE_001_DSM.txt: size: is 256 but"),
            std::string::npos) << Find(r, "SIZE_001").report.message;
}

TEST_F(IngestBadInput, AoiFilterAndUnknownAoi) {
  LinkImage("ONE_001", "001", "001");
  LinkImage("TWO_002", "001", "002");
  IngestOptions o;
  o.aois = {"TWO_002", "NONE_009"};
  const IngestResult r = Run(o);
  ASSERT_EQ(r.aois.size(), 2u);
  EXPECT_EQ(Find(r, "TWO_002").report.status, StageStatus::kOk);
  EXPECT_NE(Find(r, "NONE_009").report.message.find("no images of this AOI"), std::string::npos);
}

TEST_F(IngestBadInput, RootWithoutImageFoldersIsAnError) {
  const std::string msg = ErrorText([&] { Run(); });
  EXPECT_NE(msg.find("holds no Track3-RGB or Track3-RGB-crops folder"), std::string::npos) << msg;
  EXPECT_NE(ErrorText([&] {
              NullProgress p;
              RunIngest({}, "/nonexistent/root", "/tmp/x", p);
            }).find("is not a folder"),
            std::string::npos);
}

TEST_F(IngestBadInput, ReadsTheFlatTrack3RgbLayout) {
  // The original DFC2019 release keeps every AOI's images in one folder.
  const fs::path flat = root_ / "Track3-RGB-1";
  fs::create_directories(flat);
  fs::create_symlink(Jax068Image("001"), flat / "FLAT_001_001_RGB.tif");
  fs::create_symlink(Jax068Image("002"), flat / "FLAT_001_002_RGB.tif");
  fs::create_symlink(Jax068Image("003"), flat / "OTHER_002_001_RGB.tif");
  const IngestResult r = Run();
  EXPECT_EQ(r.NumIngested(), 2);
  EXPECT_EQ(Find(r, "FLAT_001").catalog.images.size(), 2u);
  EXPECT_EQ(Find(r, "OTHER_002").catalog.images.size(), 1u);
}

TEST_F(IngestBadInput, RerunReplacesTheCatalogAtomically) {
  LinkImage("RE_001", "001", "001");
  const IngestResult first = Run();
  const std::string path = Find(first, "RE_001").catalog_path;
  const auto before = ReadAoiCatalog(path);
  LinkImage("RE_001", "002", "002");
  const IngestResult second = Run();
  EXPECT_EQ(ReadAoiCatalog(path).images.size(), before.images.size() + 1);
  for (const auto& e : fs::directory_iterator(fs::path(path).parent_path()))
    EXPECT_EQ(e.path().filename(), "aoi.json");  // no temporaries left behind
}

}  // namespace
}  // namespace skyfall
