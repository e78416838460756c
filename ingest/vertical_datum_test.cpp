#include "ingest/vertical_datum.h"

#include <gdal.h>
#include <cpl_conv.h>
#include <ogr_srs_api.h>
#include <gtest/gtest.h>

#include <cmath>

#include "ingest/geo.h"
#include "ingest/raster.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

// JAX_068's centre (lon, lat): where the DFC2019 truth lies.
const Eigen::Vector2d kJacksonville(-81.6636, 30.3577);
constexpr int kUtm17N = 32617;

// An independent evaluation of the geoid: egm96_15.gtx read as a raster
// (cell-centred 0.25 deg lattice) and interpolated bilinearly.
double UndulationFromGridFile(double lon, double lat) {
  GDALAllRegister();
  GDALDatasetH ds = GDALOpen("/usr/share/proj/egm96_15.gtx", GA_ReadOnly);
  if (!ds) return NAN;
  double gt[6];
  GDALGetGeoTransform(ds, gt);
  const double u = (lon - gt[0]) / gt[1] - 0.5, v = (lat - gt[3]) / gt[5] - 0.5;
  const int i = static_cast<int>(std::floor(u)), j = static_cast<int>(std::floor(v));
  float cells[4];
  const CPLErr read = GDALRasterIO(GDALGetRasterBand(ds, 1), GF_Read, i, j, 2, 2, cells, 2, 2, GDT_Float32, 0, 0);
  GDALClose(ds);
  if (read != CE_None) return NAN;
  const double fu = u - i, fv = v - j;
  return (1 - fv) * ((1 - fu) * cells[0] + fu * cells[1]) + fv * ((1 - fu) * cells[2] + fu * cells[3]);
}

DsmGrid FlatGridAtJacksonville(float height_m) {
  const Eigen::Vector2d utm = UtmFromGeodetic(UtmZoneFromEpsg(kUtm17N), kJacksonville.x(), kJacksonville.y());
  DsmGrid g;
  g.width_px = 40;
  g.height_px = 30;
  g.gsd_m = 0.5;
  g.epsg = kUtm17N;
  g.upper_left_easting_m = utm.x() - 10;
  g.upper_left_northing_m = utm.y() + 7.5;
  g.height_m.assign(static_cast<std::size_t>(g.width_px) * g.height_px, height_m);
  g.height_m[7] = NAN;
  return g;
}

// PROJ's value and a bilinear read of the grid file agree to the grid's own
// interpolation differences (PROJ interpolates the same lattice: 1 cm).
TEST(VerticalDatum, UndulationAtJacksonvilleMatchesTheGridFile) {
  const double expected = UndulationFromGridFile(kJacksonville.x(), kJacksonville.y());
  ASSERT_TRUE(std::isfinite(expected)) << "egm96_15.gtx of proj-data is missing";
  const double n = Egm96UndulationsM({kJacksonville}).at(0);
  EXPECT_NEAR(n, expected, 0.01);
  EXPECT_NEAR(n, -29.7, 0.2);  // the geoid lies about 30 m below the ellipsoid in Florida
}

TEST(VerticalDatum, ConversionShiftsByTheUndulationAndRoundTrips) {
  DsmGrid g = FlatGridAtJacksonville(10.0f);
  const double n = Egm96UndulationsM({kJacksonville}).at(0);
  ConvertHeightReference(&g, HeightReference::kEgm96, "test");
  EXPECT_EQ(g.reference, HeightReference::kEgm96);
  // 20 m across: the geoid's slope there is millimetres.
  EXPECT_NEAR(g.At(20, 15), 10.0 - n, 0.005);
  EXPECT_TRUE(std::isnan(g.height_m[7]));  // nodata stays nodata
  ConvertHeightReference(&g, HeightReference::kEllipsoid, "test");
  for (std::size_t k = 0; k < g.height_m.size(); ++k) {
    if (k == 7) continue;
    ASSERT_NEAR(g.height_m[k], 10.0f, 1e-4) << k;
  }
}

TEST(VerticalDatum, HeightsAboveTheTerrainHaveNoDatumToConvertTo) {
  DsmGrid g = FlatGridAtJacksonville(3.0f);
  const std::string message =
      ErrorText([&] { ConvertHeightReference(&g, HeightReference::kAboveTerrain, "ndsm.tif"); });
  EXPECT_NE(message.find("ndsm.tif"), std::string::npos) << message;
}

// A GeoTIFF states its heights' frame in its CRS, and reading it gives the
// same frame back; an unconvertible vertical CRS is refused by name.
TEST(VerticalDatum, RastersStateTheirReference) {
  const fs::path dir = ScratchDir("vertical_datum");
  const DsmGrid g = FlatGridAtJacksonville(1.0f);
  NorthUpGrid grid{g.upper_left_easting_m, g.upper_left_northing_m, g.gsd_m, g.epsg, std::nullopt};
  for (HeightReference r : {HeightReference::kEllipsoid, HeightReference::kEgm96}) {
    grid.heights = r;
    const fs::path path = dir / (std::string(EnumName(r)) + ".tif");
    WriteFloatCog(path.string(), g.width_px, g.height_px, g.height_m.data(), grid);
    EXPECT_EQ(HeightReferenceOfRaster(path.string()), r);
    EXPECT_EQ(ReadGeoGrid(path.string()).epsg, kUtm17N);
    // The CRS is in the GeoTIFF keys, not in a side file a copy would lose:
    // read with side files off, EGM96 heights are a compound CRS with
    // EPSG:5773, ellipsoidal ones the plain zone.
    CPLSetConfigOption("GDAL_PAM_ENABLED", "NO");
    GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
    CPLSetConfigOption("GDAL_PAM_ENABLED", nullptr);
    ASSERT_NE(ds, nullptr);
    OGRSpatialReferenceH srs = GDALGetSpatialRef(ds);
    ASSERT_NE(srs, nullptr) << path;
    EXPECT_EQ(OSRIsCompound(srs) != 0, r == HeightReference::kEgm96);
    if (r == HeightReference::kEgm96) {
      ASSERT_NE(OSRGetAuthorityCode(srs, "VERT_CS"), nullptr);
      EXPECT_STREQ(OSRGetAuthorityCode(srs, "VERT_CS"), "5773");
    }
    EXPECT_STREQ(GDALGetMetadataItem(ds, kHeightReferenceItem, nullptr), EnumName(r));
    GDALClose(ds);
  }
  grid.heights.reset();
  WriteFloatCog((dir / "plain.tif").string(), g.width_px, g.height_px, g.height_m.data(), grid);
  EXPECT_FALSE(HeightReferenceOfRaster((dir / "plain.tif").string()).has_value());

  const fs::path navd = dir / "navd88.tif";
  {
    GDALDatasetH ds = GDALCreate(GDALGetDriverByName("GTiff"), navd.c_str(), 4, 4, 1, GDT_Float32, nullptr);
    ASSERT_NE(ds, nullptr);
    OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
    OSRSetFromUserInput(srs, "EPSG:32617+5703");  // UTM 17N + NAVD88 height
    GDALSetSpatialRef(ds, srs);
    OSRDestroySpatialReference(srs);
    double gt[6] = {440000, 1, 0, 3360000, 0, -1};
    GDALSetGeoTransform(ds, gt);
    GDALClose(ds);
  }
  const std::string message = ErrorText([&] { HeightReferenceOfRaster(navd.string()); });
  EXPECT_NE(message.find(navd.string()), std::string::npos) << message;
  EXPECT_NE(message.find("NAVD88"), std::string::npos) << message;
  EXPECT_NE(message.find("WGS84 ellipsoid"), std::string::npos) << message;  // the frame it would be compared in
  // A tool that converted the heights changed the CRS and copied the old
  // metadata item: the CRS decides.
  {
    GDALDatasetH ds = GDALOpen(navd.c_str(), GA_Update);
    ASSERT_NE(ds, nullptr);
    GDALSetMetadataItem(ds, kHeightReferenceItem, "egm96", nullptr);
    GDALClose(ds);
  }
  EXPECT_NE(ErrorText([&] { HeightReferenceOfRaster(navd.string()); }).find("NAVD88"), std::string::npos);
}

}  // namespace
}  // namespace skyfall
