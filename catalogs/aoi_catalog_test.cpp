#include "catalogs/aoi_catalog.h"

#include <gtest/gtest.h>

#include "core/error.h"
#include "tests/test_rpc_fixture.h"

namespace skyfall {
namespace {

AoiCatalog MakeCatalog() {
  AoiCatalog c;
  c.aoi = "TST_001";
  c.source_root = "/data/root";
  c.enu_origin = {-81.66377836684407, 30.3487524532743, 1.5};
  c.utm_zone = 17;
  c.utm_north = true;
  c.epsg = 32617;
  c.footprint_lonlat = {{-81.665, 30.347}, {-81.662, 30.347}, {-81.662, 30.350}, {-81.665, 30.350}};
  c.footprint_source = "truth_grid";
  c.min_ellipsoid_height_m = -31.25;
  c.max_ellipsoid_height_m = 34.125;
  c.height_range_source = "truth_dsm";
  ImageRecord im;
  im.name = "TST_001_001_RGB";
  im.path = "/data/root/Track3-RGB-crops/TST_001/TST_001_001_RGB.tif";
  im.width_px = 746;
  im.height_px = 815;
  im.bands = 3;
  im.dtype = "Byte";
  im.rpc = testing::MakeTestRpc();
  im.rpc_source = "gdal_metadata";
  im.acquisition_time = "2014-10-05T16:01:38Z";
  im.sun_elevation_deg = 50.8;
  im.view_zenith_deg = 21.3;
  im.view_azimuth_deg = 187.5;
  im.off_nadir_deg = 19.4;
  im.footprint_lonlat = c.footprint_lonlat;
  c.images.push_back(im);
  TruthGrid t;
  t.dsm_path = "a_DSM.tif";
  t.dsm_txt_path = "a_DSM.txt";
  t.epsg = 32617;
  t.lower_left_easting_m = 436078.995946;
  t.lower_left_northing_m = 3357495.999923;
  t.width_px = t.height_px = 512;
  t.gsd_m = 0.5;
  c.truth = t;
  c.train_images = {"TST_001_001_RGB"};
  return c;
}

TEST(AoiCatalog, JsonRoundTripIsExact) {
  const AoiCatalog c = MakeCatalog();
  const AoiCatalog back = AoiCatalogFromJson(AoiCatalogToJson(c), "mem");
  EXPECT_EQ(back.aoi, c.aoi);
  EXPECT_EQ(back.enu_origin.lon_deg, c.enu_origin.lon_deg);  // doubles survive exactly
  EXPECT_EQ(back.epsg, 32617);
  ASSERT_EQ(back.images.size(), 1u);
  EXPECT_EQ(back.images[0].rpc.line_num, c.images[0].rpc.line_num);
  EXPECT_EQ(back.images[0].rpc.samp_off, c.images[0].rpc.samp_off);
  EXPECT_EQ(back.images[0].sun_elevation_deg, 50.8);
  EXPECT_FALSE(back.images[0].sun_azimuth_deg.has_value());
  ASSERT_TRUE(back.truth.has_value());
  EXPECT_EQ(back.truth->lower_left_northing_m, 3357495.999923);
  EXPECT_DOUBLE_EQ(back.truth->UpperLeftNorthing(), 3357495.999923 + 256.0);
  EXPECT_TRUE(back.truth->cls_path.empty());
  EXPECT_EQ(back.train_images, c.train_images);
}

TEST(AoiCatalog, RejectsWrongSchemaAndBrokenRpc) {
  std::string text = AoiCatalogToJson(MakeCatalog());
  std::string wrong = text;
  wrong.replace(wrong.find("skyfall.aoi/1"), 13, "skyfall.aoi/9");
  EXPECT_THROW(AoiCatalogFromJson(wrong, "x.json"), Error);
  std::string broken = text;
  const auto pos = broken.find("\"LAT_SCALE\": ");
  broken.replace(pos, std::string("\"LAT_SCALE\": ").size(), "\"LAT_SCALE\": 0.0, \"x\": ");
  try {
    AoiCatalogFromJson(broken, "x.json");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("x.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("LAT_SCALE"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace skyfall
