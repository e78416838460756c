// The GIS products of a whole run: every raster a valid COG in its stated
// height reference, the point cloud read back by two readers, the figures in
// the run report, and an EGM96 run that differs from the ellipsoidal one by
// the geoid's undulation.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <ogr_srs_api.h>

#include "catalogs/aoi_catalog.h"
#include "ingest/geo.h"
#include "ingest/radiometry.h"
#include "ingest/vertical_datum.h"
#include "products/dsm.h"
#include "products/gis_layers.h"
#include "products/point_cloud.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

nlohmann::json ReadJson(const fs::path& path) { return nlohmann::json::parse(std::ifstream(path)); }

CommandResult ValidateCog(const fs::path& path) {
  return RunCommand("/usr/bin/python3 /usr/lib/python3/dist-packages/osgeo_utils/samples/"
                    "validate_cloud_optimized_geotiff.py " + path.string(), path.parent_path());
}

// The tolerance of the EGM96 comparison: the 0.1 m, far above the
// float32 rounding of heights near 30 m (4 um) and the geoid's change across
// a 64 m AOI (millimetres).
constexpr double kDatumToleranceM = 0.1;

TEST(CliProducts, EveryAoiGetsItsGisProductsInAStatedDatum) {
  const fs::path dir = ScratchDir("cli_products");
  const std::string root = (dir / "tree").string(), out = (dir / "out").string();
  ASSERT_EQ(RunCommand(Skyfall() + " synth --out " + root + " --aoi SYN_001 --size-m 64 --views 3 --seed 4", dir)
                .exit_code, 0);
  const std::string run = Skyfall() + " run " + root + " --out " + out +
                          " --tile-m 64 --iterations 30 --init-max-scale 0 --idu off";
  const CommandResult first = RunCommand(run, dir);
  ASSERT_EQ(first.exit_code, 0) << first.err;
  const fs::path aoi = fs::path(out) / "SYN_001";
  for (const char* name : {"dsm.tif", "dtm.tif", "ndsm.tif", "quality.tif", "ortho.tif", "classes.tif"}) {
    ASSERT_TRUE(fs::exists(aoi / name)) << name;
    const CommandResult cog = ValidateCog(aoi / name);
    EXPECT_EQ(cog.exit_code, 0) << name << ": " << cog.out << cog.err;
  }
  EXPECT_EQ(HeightReferenceOfRaster((aoi / "dsm.tif").string()), HeightReference::kEllipsoid);
  EXPECT_EQ(HeightReferenceOfRaster((aoi / "dtm.tif").string()), HeightReference::kEllipsoid);
  EXPECT_EQ(HeightReferenceOfRaster((aoi / "ndsm.tif").string()), HeightReference::kAboveTerrain);

  // The report holds the terrain and ortho figures of the AOI with truth.
  // This small scene has ground and a river but no building; its DTM was
  // measured 1.97 m low on the ground (the terrain model's plane tilts to
  // the river): the bound catches a wrong frame or datum (tens of metres),
  // not the model's weakness.
  const nlohmann::json report = ReadJson(fs::path(out) / "SYN_001" / "run_report.json");
  const nlohmann::json& dsm = report.at("dsm").at(0);
  EXPECT_LT(dsm.at("terrain").at("dtm_mae_ground_m").get<double>(), 5.0) << dsm.dump();
  EXPECT_GT(dsm.at("terrain").at("ground_cells").get<int>(), 1000) << dsm.dump();
  EXPECT_GT(dsm.at("ortho").at("psnr_db").get<double>(), 15.0) << dsm.dump();
  EXPECT_GT(dsm.at("ortho").at("ground_cells").get<int>(), 1000) << dsm.dump();

  // The synthetic city's exact orthophoto: the run's ortho is compared with
  // it, and it agrees with the image closest to nadir on the ground that
  // image sees (same renderer and light; the image adds +-1 DN of noise and
  // its RPC's resampling): a check of the truth itself and of the protocol.
  const nlohmann::json& exact = dsm.at("ortho_truth");
  EXPECT_GT(exact.at("psnr_db").get<double>(), 15.0) << exact.dump();
  EXPECT_GT(exact.at("cells").get<int>(), 10000) << exact.dump();
  const AoiCatalog catalog = ReadAoiCatalog((fs::path(out) / "catalogs" / "SYN_001" / "aoi.json").string());
  ASSERT_TRUE(catalog.truth && !catalog.truth->ortho_path.empty());
  const ImageRecord* nadir = &catalog.images.front();
  for (const ImageRecord& image : catalog.images)
    if (image.view_zenith_deg < nadir->view_zenith_deg) nadir = &image;
  const NormalizedImage truth_ortho = ReadNormalizedImage(catalog.truth->ortho_path, nadir->radiometry);
  std::vector<float> truth_rgb(truth_ortho.rgb.begin(), truth_ortho.rgb.end());
  const TruthDsm truth = ReadTruthDsm(*catalog.truth);
  const OrthoAgreement against_image =
      CompareOrthoWithImage(truth_rgb, truth.dsm, truth.cls, ReadNormalizedImage(nadir->path, nadir->radiometry),
                            nadir->rpc, nadir->view_zenith_deg, nadir->view_azimuth_deg);
  EXPECT_GT(against_image.psnr_db, 28.0) << against_image.cells;
  EXPECT_GT(against_image.ssim, 0.8);
  EXPECT_EQ(against_image.shift_col_px, 0);
  EXPECT_EQ(against_image.shift_row_px, 0);

  // The point cloud (points.laz by default): our reader and laz-perf agree
  // with the report, the points lie on the AOI, the CRS is UTM 17N with
  // ellipsoidal heights, and the catalog says so.
  const nlohmann::json& products = report.at("products").at(0);
  const LasHeaderInfo las = ReadLasHeader((aoi / "points.laz").string());
  EXPECT_TRUE(las.compressed);
  EXPECT_EQ(las.point_count, products.at("points").at("count").get<std::uint64_t>());
  EXPECT_EQ(products.at("points").at("encoding"), "laz");
  EXPECT_GT(las.point_count, 1000u);
  const DsmGrid grid = ReadDsm((aoi / "dsm.tif").string());
  EXPECT_GE(las.min_x, grid.upper_left_easting_m);
  EXPECT_LE(las.max_x, grid.upper_left_easting_m + grid.width_px * grid.gsd_m);
  EXPECT_LE(las.max_y, grid.upper_left_northing_m);
  EXPECT_GE(las.min_y, grid.upper_left_northing_m - grid.height_px * grid.gsd_m);
  OGRSpatialReferenceH crs = OSRNewSpatialReference(las.crs_wkt.c_str());
  ASSERT_NE(crs, nullptr);
  EXPECT_EQ(OSRGetAxesCount(crs), 3);
  OSRDestroySpatialReference(crs);
  const nlohmann::json points_asset = ReadJson(aoi / "SYN_001.json").at("assets").at("points");
  EXPECT_EQ(points_asset.at("type"), "application/vnd.laszip");
  EXPECT_EQ(points_asset.at("proj:code"), "EPSG:32617");
  EXPECT_EQ(points_asset.at("proj:bbox").at(2).get<double>(), las.min_z);
  const fs::path web = fs::path(SKYFALL_SOURCE_DIR) / "web";
  const bool decoders = fs::exists(web / "node_modules" / "laz-perf") && fs::exists(web / "node_modules" / "copc");
  const auto decode = [&](const fs::path& file) {
    const CommandResult r = RunCommand("node " + (web / "check_points.mjs").string() + " " + file.string(), dir);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.exit_code == 0 ? nlohmann::json::parse(r.out) : nlohmann::json::object();
  };
  nlohmann::json laz;
  if (decoders) {
    laz = decode(aoi / "points.laz");
    EXPECT_EQ(laz.at("decoded").get<std::uint64_t>(), las.point_count) << laz.dump();
    EXPECT_EQ(laz.at("crs_wkt"), las.crs_wkt);
    const double scale[] = {las.scale_x, las.scale_y, las.scale_z}, offset[] = {las.offset_x, las.offset_y, las.offset_z};
    const double mins[] = {las.min_x, las.min_y, las.min_z}, maxs[] = {las.max_x, las.max_y, las.max_z};
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(laz.at("scale").at(a).get<double>(), scale[a]) << "axis " << a;
      EXPECT_EQ(laz.at("offset").at(a).get<double>(), offset[a]) << "axis " << a;
      // The decoded records' bounds are the header's: both are stored integers times the
      // scale plus the offset, equal up to the last bits of a double (1 um is far below them
      // and far below the 1 mm step).
      EXPECT_NEAR(laz.at("mins").at(a).get<double>(), mins[a], 1e-6) << "axis " << a;
      EXPECT_NEAR(laz.at("maxs").at(a).get<double>(), maxs[a], 1e-6) << "axis " << a;
    }
    EXPECT_GT(laz.at("classes").value("2", 0), 0);  // ground
  }

  // The report page: the orthophoto beside the DSM and the quality layers,
  // the figures against the truth (the exact orthophoto's too), and a link
  // to the point cloud.
  {
    std::ifstream page_file(fs::path(out) / "report.html");
    const std::string page((std::istreambuf_iterator<char>(page_file)), {});
    const std::size_t ortho_at = page.find("<figcaption>Orthophoto"), dsm_at = page.find("<figcaption>DSM"),
                      views_at = page.find("<figcaption>Views that see"),
                      rule_at = page.find("<figcaption>How each cell got its height");
    ASSERT_NE(ortho_at, std::string::npos);
    ASSERT_NE(dsm_at, std::string::npos);
    ASSERT_NE(views_at, std::string::npos);
    ASSERT_NE(rule_at, std::string::npos);
    EXPECT_LT(ortho_at, dsm_at);
    EXPECT_LT(dsm_at, views_at);
    EXPECT_NE(page.find("ortho vs exact orthophoto"), std::string::npos);
    EXPECT_NE(page.find("DTM on ground: MAE"), std::string::npos);
    EXPECT_NE(page.find("href=\"SYN_001/points.laz\""), std::string::npos);
  }

  // Heights above EGM96: the same surface less the undulation (N = -29.7 m
  // here, so 29.7 m higher); the comparison still runs on ellipsoidal heights.
  const DsmGrid ellipsoidal = grid;
  const CommandResult egm = RunCommand(run + " --set products.vertical_datum=egm96", dir);
  ASSERT_EQ(egm.exit_code, 0) << egm.err;
  const DsmGrid orthometric = ReadDsm((aoi / "dsm.tif").string());
  EXPECT_EQ(orthometric.reference, HeightReference::kEgm96);
  const Eigen::Vector2d centre = GeodeticFromUtm(
      UtmZoneFromEpsg(grid.epsg), grid.upper_left_easting_m + 0.5 * grid.width_px * grid.gsd_m,
      grid.upper_left_northing_m - 0.5 * grid.height_px * grid.gsd_m);
  const double n = Egm96UndulationsM({centre}).at(0);
  EXPECT_NEAR(n, -29.7, 0.3);
  int compared = 0;
  for (std::size_t p = 0; p < grid.height_m.size(); ++p) {
    if (!std::isfinite(ellipsoidal.height_m[p])) continue;
    ASSERT_NEAR(orthometric.height_m[p] - ellipsoidal.height_m[p], -n, kDatumToleranceM) << p;
    ++compared;
  }
  EXPECT_GT(compared, 1000);
  const nlohmann::json again = ReadJson(fs::path(out) / "SYN_001" / "run_report.json");
  EXPECT_NEAR(again.at("dsm").at(0).at("mae_m").get<double>(), dsm.at("mae_m").get<double>(), 1e-9);
  EXPECT_EQ(again.at("products").at(0).at("vertical_datum"), "egm96");
  // The points moved up by the same undulation, and their CRS says EGM96.
  const LasHeaderInfo las_egm = ReadLasHeader((aoi / "points.laz").string());
  EXPECT_NEAR(las_egm.min_z - las.min_z, -n, kDatumToleranceM);
  EXPECT_NE(las_egm.crs_wkt.find("EGM96"), std::string::npos) << las_egm.crs_wkt;

  // COPC on request: points.copc.laz replaces points.laz, holds the same
  // records, every point inside its octree node, and is catalogued as COPC.
  const CommandResult copc_run = RunCommand(run + " --set products.points_format=copc", dir);
  ASSERT_EQ(copc_run.exit_code, 0) << copc_run.err;
  EXPECT_FALSE(fs::exists(aoi / "points.laz"));
  ASSERT_TRUE(fs::exists(aoi / "points.copc.laz"));
  EXPECT_TRUE(ReadLasHeader((aoi / "points.copc.laz").string()).copc);
  EXPECT_EQ(ReadJson(aoi / "SYN_001.json").at("assets").at("points").at("type"), "application/vnd.laszip+copc");
  if (decoders) {
    const nlohmann::json copc = decode(aoi / "points.copc.laz");
    EXPECT_EQ(copc.at("format"), "copc");
    EXPECT_EQ(copc.at("outside"), 0);
    EXPECT_EQ(copc.at("node_points"), copc.at("count"));
    EXPECT_EQ(copc.at("records_sha256"), laz.at("records_sha256"));
  }

  // A product turned off is said to be left out, and its file from the
  // previous run goes: the catalog and the page list only what the run made.
  const CommandResult without = RunCommand(run + " --set products.points=false", dir);
  ASSERT_EQ(without.exit_code, 0) << without.err;
  for (const char* name : {"points.las", "points.laz", "points.copc.laz"}) EXPECT_FALSE(fs::exists(aoi / name));
  const nlohmann::json last = ReadJson(fs::path(out) / "SYN_001" / "run_report.json");
  EXPECT_EQ(last.at("products").at(0).at("left_out").at(0), "point cloud (products.points off)");
  EXPECT_FALSE(ReadJson(aoi / "SYN_001.json").at("assets").contains("points"));
}

}  // namespace
}  // namespace skyfall
