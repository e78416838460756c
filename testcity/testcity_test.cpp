#include "testcity/testcity.h"

#include <gtest/gtest.h>

#include <functional>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <regex>
#include <nlohmann/json.hpp>
#include <set>

#include "catalogs/aoi_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/test_support.h"
#include "ingest/dfc2019.h"
#include "ingest/geo.h"
#include "ingest/height_probe.h"
#include "ingest/raster.h"
#include "ingest/rpc_io.h"
#include "tiling/tiling.h"
#include "testcity/test_scene.h"

namespace skyfall::synth {
namespace {

using namespace skyfall::testing;
using namespace skyfall::synth::testing_scene;

TEST(Synth, IngestReadsTheSceneLikeRealData) {
  const Scene s = MakeScene(SmallScene());
  NullProgress progress;
  const IngestResult r = RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress);
  ASSERT_EQ(r.NumIngested(), 1);
  const AoiCatalog& c = r.aois.at(0).catalog;
  EXPECT_EQ(c.aoi, "SYN_001");
  ASSERT_EQ(c.images.size(), 4u);
  EXPECT_EQ(c.epsg, 32617);
  ASSERT_TRUE(c.truth.has_value());
  EXPECT_EQ(c.truth->width_px, 256);
  EXPECT_EQ(c.height_range_source, "truth_dsm");
  EXPECT_EQ(c.test_images.size(), 2u);
  EXPECT_EQ(c.train_images.size(), 2u);
  for (size_t i = 0; i < c.images.size(); ++i) {
    const ImageRecord& im = c.images[i];
    const SynthView& v = s.result.aois[0].views[i];
    EXPECT_EQ(im.rpc_source, "gdal_metadata");
    EXPECT_EQ(im.acquisition_time, v.acquisition_time);
    ASSERT_TRUE(im.sun_elevation_deg.has_value());
    EXPECT_NEAR(*im.sun_elevation_deg, v.sun_elevation_deg, 1e-9);
    // Ingest derives the viewing geometry from the RPC alone: it agrees
    // with the camera that made the image.
    EXPECT_NEAR(im.view_zenith_deg, v.view_zenith_deg, 0.1) << im.name;
    EXPECT_NEAR(im.off_nadir_deg, v.off_nadir_deg, 0.1) << im.name;
    const double daz = std::remainder(im.view_azimuth_deg - v.view_azimuth_deg, 360.0);
    EXPECT_LT(std::abs(daz), 0.5) << im.name;
  }
}

// Passes fall at about 10:30 local solar time at any longitude, as a
// sun-synchronous satellite's do: over a mid-latitude city far east or west
// of the default one the sun is up (at 45 S in its winter, 10:30 puts it
// about 18 deg high; 10 deg leaves room for the approximate solar position),
// and at the default longitude the times are those of before.
TEST(Synth, PassesFallInTheLocalMorningAtAnyLongitude) {
  constexpr double kMinSunElevationDeg = 10.0;
  for (const double lon_deg : {-170.0, 0.0, 100.0, 170.5}) {
    SynthOptions o = SmallScene();
    o.size_m = 64.0;
    o.views = 4;
    o.views_per_date = 1;  // four dates, January to June
    o.lat_deg = -45.0;
    o.lon_deg = lon_deg;
    const Scene s = MakeScene(o);
    for (const SynthView& v : s.result.aois[0].views)
      EXPECT_GT(v.sun_elevation_deg, kMinSunElevationDeg) << "lon " << lon_deg << " " << v.acquisition_time;
  }
  const Scene reference = MakeScene(SmallScene());
  EXPECT_EQ(reference.result.aois[0].views[0].acquisition_time, "2015-01-15T15:55:00Z");
}

// Stiff and extreme geometry (docs/reliability.md lists each case and its
// outcome): far north and south, a UTM zone boundary, steep views, a 300 m
// tower, fine and coarse GSD. In each the written RPCs reproduce the true
// cameras within kRpcFitTolPx, and ingest reads the viewing geometry back
// from the RPCs alone within 0.1 deg. The antimeridian is an open finding
// (see the docs), not a case that passes.
struct ExtremeCase {
  const char* name;
  std::function<void(SynthOptions&)> set;
};

TEST(Synth, ExtremeScenesKeepTheirRpcsAndViewGeometry) {
  const std::vector<ExtremeCase> cases = {
      {"lat 80 N", [](SynthOptions& o) { o.lat_deg = 80.0; o.lon_deg = 15.0; }},
      {"lat 79.9 S", [](SynthOptions& o) { o.lat_deg = -79.9; o.lon_deg = -57.0; }},
      // On the boundary of zones 20 and 21: the images' centre falls in one,
      // the truth grid (DSM.txt, no CRS) was written in the other.
      {"UTM zone boundary", [](SynthOptions& o) { o.lon_deg = -60.0; }},
      {"zone boundary, 60 S", [](SynthOptions& o) { o.lat_deg = -60.0; o.lon_deg = -60.0; }},
      // Astride the antimeridian: the AOI spans 179.9992 E to 179.9998 W.
      {"antimeridian", [](SynthOptions& o) { o.lon_deg = 179.9995; }},
      {"antimeridian, 60 S", [](SynthOptions& o) { o.lat_deg = -60.0; o.lon_deg = -179.9995; }},
      // HEIGHT_OFF 1500 m above and 800 m below the ground: the scene sits
      // at one face of the RPCs' validity cube.
      {"RPC HEIGHT_OFF 1500 m above", [](SynthOptions& o) { o.rpc_height_offset_m = 1500.0; }},
      {"RPC HEIGHT_OFF 800 m below", [](SynthOptions& o) { o.rpc_height_offset_m = -800.0; }},
      {"45 deg off nadir", [](SynthOptions& o) { o.min_off_nadir_deg = 40.0; o.max_off_nadir_deg = 45.0; }},
      {"300 m tower", [](SynthOptions& o) { o.max_building_m = 300.0; }},
      {"GSD 0.3 m", [](SynthOptions& o) { o.gsd_m = 0.3; o.size_m = 60.0; }},
      {"GSD 2 m", [](SynthOptions& o) { o.gsd_m = 2.0; o.size_m = 256.0; }},
      // A city 4,000 m above the ellipsoid (La Paz, El Alto).
      {"ground 4000 m", [](SynthOptions& o) { o.ground_height_m = 4000.0; }},
      // A three-line camera: forward, nadir, backward on one track (ZY-3).
      {"three-line +-22 deg", [](SynthOptions& o) { o.along_track_deg = 22.0; o.views_per_date = 3; }},
  };
  for (const ExtremeCase& c : cases) {
    SynthOptions o = SmallScene();
    o.size_m = 64.0;  // a whole number of GSDs (cases may change both)
    o.views = 3;
    c.set(o);
    const Scene s = MakeScene(o);
    NullProgress progress;
    const IngestResult r = RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress);
    ASSERT_EQ(r.NumIngested(), 1) << c.name << ": " << r.aois.at(0).report.message;
    const AoiCatalog& catalog = r.aois.at(0).catalog;
    for (std::size_t i = 0; i < catalog.images.size(); ++i) {
      const SynthView& v = s.result.aois[0].views[i];
      EXPECT_LE(v.rpc_fit_max_px, kRpcFitTolPx) << c.name << " " << v.name;
      EXPECT_NEAR(catalog.images[i].off_nadir_deg, v.off_nadir_deg, 0.1) << c.name << " " << v.name;
      EXPECT_NEAR(catalog.images[i].view_zenith_deg, v.view_zenith_deg, 0.1) << c.name << " " << v.name;
    }
    std::printf("[figures] %s: EPSG %d, worst RPC fit %.2g px\n", c.name, catalog.epsg,
                std::max_element(s.result.aois[0].views.begin(), s.result.aois[0].views.end(),
                                 [](const SynthView& a, const SynthView& b) { return a.rpc_fit_max_px < b.rpc_fit_max_px; })
                    ->rpc_fit_max_px);
  }
}

// Without truth or Sat-NeRF altitudes the height range comes from the RPCs.
// Their HEIGHT_OFF may lie far from the AOI's ground (the middle of a
// vendor's whole scene): ingest then finds the ground where the views agree.
// Near HEIGHT_OFF, the range stays centred on it as before.
TEST(Synth, RpcOnlyHeightRangeFindsTheGroundFarFromHeightOff) {
  for (const double offset_m : {1500.0, -800.0, 0.0}) {
    SynthOptions o = SmallScene();
    o.size_m = 64.0;
    o.views = 3;
    o.rpc_height_offset_m = offset_m;
    const Scene s = MakeScene(o);
    fs::remove_all(s.root / "Track3-Truth");
    fs::remove_all(s.root / "satnerf-rpcs");
    NullProgress progress;
    const IngestResult r = RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress);
    ASSERT_EQ(r.NumIngested(), 1) << "offset " << offset_m << ": " << r.aois.at(0).report.message;
    const AoiCatalog& c = r.aois.at(0).catalog;
    EXPECT_EQ(c.height_range_source, offset_m == 0.0 ? "rpc" : "rpc_height_probe") << offset_m;
    // The whole scene, ground to roofs, inside the searched range.
    EXPECT_LE(c.min_ellipsoid_height_m, s.result.city.min_height_m) << offset_m;
    EXPECT_GE(c.max_ellipsoid_height_m, s.result.city.max_height_m) << offset_m;
    std::printf("[figures] HEIGHT_OFF %+.0f m from the ground: range %.1f..%.1f m (%s), scene %.1f..%.1f m\n",
                offset_m, c.min_ellipsoid_height_m, c.max_ellipsoid_height_m, c.height_range_source.c_str(),
                static_cast<double>(s.result.city.min_height_m), static_cast<double>(s.result.city.max_height_m));
    // One view cannot place anything.
    EXPECT_FALSE(ProbeSceneHeight({c.images.front()}).has_value());
  }
  HeightProbeOptions bad;
  bad.fine_step_m = 5.0;  // coarser than the coarse step
  EXPECT_NE(ErrorText([&] { bad.Check(); }).find("fine_step_m"), std::string::npos);
}

// The options that make real sensors' defect classes: a city far above the
// ellipsoid, biased RPCs, a three-line camera.
TEST(Synth, GroundHeightLiftsTheWholeSceneAndItsRpcs) {
  SynthOptions o = SmallScene();
  o.size_m = 64.0;
  o.views = 3;
  o.ground_height_m = 2300.0;
  const Scene s = MakeScene(o);
  EXPECT_GT(s.result.city.min_height_m, 2200.0);
  EXPECT_LT(s.result.city.max_height_m, 2300.0 + o.max_building_m + 50.0);
  EXPECT_NEAR(s.result.enu_origin.height_m, 2300.0, 60.0);
  const FloatBand dsm = ReadFloatBand((s.root / "Track3-Truth" / (o.aoi + "_DSM.tif")).string());
  EXPECT_GT(*std::min_element(dsm.values.begin(), dsm.values.end()), 2200.0f);
  for (const SynthView& v : s.result.aois[0].views) {
    EXPECT_NEAR(ReadRpcFromRaster(v.path).height_off, 2300.0, 100.0) << v.name;
    EXPECT_LE(v.rpc_fit_max_px, kRpcFitTolPx) << v.name;
  }
}

TEST(Synth, BiasedRpcsPointOffTheCameraByTheRecordedBias) {
  SynthOptions o = SmallScene();
  o.size_m = 64.0;
  o.views = 4;
  o.rpc_bias_px = 4.0;
  o.rpc_bias_rotation_deg = 0.05;
  const Scene s = MakeScene(o);
  const EnuFrame frame(s.result.enu_origin);
  const UtmZone zone = UtmZoneFromEpsg(s.result.epsg);
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile((s.root / "synth_report.json").string()));
  // What a shift v of the whole scene would do to the images: P_i v.
  const Eigen::Vector2d centre_ll = GeodeticFromUtm(zone, s.result.utm_easting0_m + 32, s.result.utm_northing0_m + 32);
  const Eigen::Vector3d centre_enu = frame.EnuFromGeodetic({centre_ll.x(), centre_ll.y(), o.ground_height_m});
  Eigen::Vector3d common = Eigen::Vector3d::Zero();  // sum P_i^T b_i: zero when no v explains any of the biases
  double largest = 0;
  for (std::size_t i = 0; i < s.result.aois[0].views.size(); ++i) {
    const SynthView& v = s.result.aois[0].views[i];
    const nlohmann::json& recorded = report.at("images").at(i);
    EXPECT_DOUBLE_EQ(recorded.at("rpc_bias_shift_px").at(0).get<double>(), v.rpc_bias_shift_px.x());
    EXPECT_DOUBLE_EQ(recorded.at("rpc_bias_rotation_deg").get<double>(), v.rpc_bias_rotation_deg);
    EXPECT_LE(v.rpc_bias_shift_px.norm(), 2 * o.rpc_bias_px);  // drawn within 4 px, less the mean
    EXPECT_LE(std::abs(v.rpc_bias_rotation_deg), o.rpc_bias_rotation_deg);
    Eigen::Matrix<double, 2, 3> jacobian;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d h = Eigen::Vector3d::Unit(k);
      jacobian.col(k) = 0.5 * (v.camera.Project(centre_enu + h) - v.camera.Project(centre_enu - h));
    }
    common += jacobian.transpose() * v.rpc_bias_shift_px;
    largest = std::max(largest, v.rpc_bias_shift_px.norm());
    const RpcModel rpc = ReadRpcFromRaster(v.path);
    const Eigen::Vector2d centre(0.5 * (v.camera.width_px - 1), 0.5 * (v.camera.height_px - 1));
    const double a = v.rpc_bias_rotation_deg * M_PI / 180.0;
    const Eigen::Matrix2d rot = (Eigen::Matrix2d() << std::cos(a), -std::sin(a), std::sin(a), std::cos(a)).finished();
    for (double fx : {0.1, 0.9})
      for (double fy : {0.1, 0.9}) {
        const double z = s.result.city.TerrainAt(fx * 64, fy * 64);
        const Eigen::Vector2d ll = GeodeticFromUtm(zone, s.result.utm_easting0_m + fx * 64,
                                                   s.result.utm_northing0_m + fy * 64);
        const Eigen::Vector2d truth = v.camera.Project(frame.EnuFromGeodetic({ll.x(), ll.y(), z}));
        const Eigen::Vector2d want = centre + rot * (truth - centre) + v.rpc_bias_shift_px;
        EXPECT_LT((rpc.Project(ll.x(), ll.y(), z) - want).norm(), kRpcFitTolPx) << v.name;
      }
  }
  // The truth's frame is the images' average: the biases hold no common
  // shift of the scene (1e-6: the Jacobians' differences over 1 m; a metre of
  // shift moves an image by about 2 px).
  EXPECT_LT(common.norm(), 1e-6);
  EXPECT_GT(largest, 1.0);
}

// A city's AOIs are crops of the same acquisitions: a crop carries its
// acquisition's bias wherever it lies, and each AOI may hold its own subset
// of the passes, so that neighbouring AOIs average different biases.
TEST(Synth, AoisOfACityShareEachAcquisitionsBiasAndHoldTheirOwnPasses) {
  SynthOptions o = SmallScene();
  o.size_m = 48.0;
  o.blocks_x = 2;
  o.views = 5;
  o.views_per_date = 1;
  o.views_per_aoi = 3;
  o.rpc_bias_px = 4.0;
  const Scene s = MakeScene(o);
  ASSERT_EQ(s.result.aois.size(), 2u);
  std::map<std::string, Eigen::Vector2d> shift_by_pass;  // "_00k_RGB" -> its shift
  std::vector<std::set<std::string>> passes(2);
  for (int a = 0; a < 2; ++a) {
    const SynthAoi& aoi = s.result.aois[a];
    ASSERT_EQ(aoi.views.size(), 3u) << aoi.name;
    for (const SynthView& v : aoi.views) {
      const std::string pass = v.name.substr(aoi.name.size());
      passes[a].insert(pass);
      EXPECT_TRUE(fs::exists(v.path)) << v.path;
      const auto [it, first] = shift_by_pass.emplace(pass, v.rpc_bias_shift_px);
      if (!first) {
        EXPECT_EQ(it->second, v.rpc_bias_shift_px) << "the crops of " << pass << " differ in bias";
      }
    }
    // Three images: no held-out split (it needs four), every image trains.
    const fs::path split = s.root / "satnerf-rpcs" / aoi.name;
    EXPECT_EQ(ReadTextFile((split / "test.txt").string()), "");
  }
  EXPECT_NE(passes[0], passes[1]) << "both AOIs drew the same passes: the option would show nothing";
  for (const auto& [pass, shift] : shift_by_pass) EXPECT_GT(shift.norm(), 0.0) << pass;
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile((s.root / "synth_report.json").string()));
  EXPECT_EQ(report.at("options").at("views_per_aoi").get<int>(), 3);
  EXPECT_EQ(report.at("images").size(), 6u);

  SynthOptions bad = o;
  bad.views_per_aoi = 1;
  EXPECT_NE(ErrorText([&] { bad.Check(); }).find("views_per_aoi"), std::string::npos);
  bad.views_per_aoi = 6;
  EXPECT_NE(ErrorText([&] { bad.Check(); }).find("views_per_aoi"), std::string::npos);
}

// Tiles are sized by the imagery unless a side is given: a 256 m tile of a
// 2 m sensor holds 128 px, too few to match, while 0.5 m imagery keeps the
// 256 m tiles every accuracy figure was measured with. A tile holds about
// tile_cells dense cells a side: 0.5 m cells for 0.5 m imagery, 1 m cells
// (half the GSD) for 2 m imagery, so 512 m tiles of 256 px.
TEST(Tiling, AutomaticTilesHoldAboutTileCellsDenseCells) {
  struct Case { double gsd_m, size_m, want_tile_m; };
  for (const Case c : {Case{0.5, 64.0, 256.0}, Case{2.0, 512.0, 512.0}}) {
    SynthOptions o = SmallScene();
    o.gsd_m = c.gsd_m;
    o.size_m = c.size_m;
    o.views = 3;
    const Scene s = MakeScene(o);
    NullProgress progress;
    const IngestResult r = RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress);
    ASSERT_EQ(r.NumIngested(), 1) << r.aois.at(0).report.message;
    const AoiCatalog& catalog = r.aois.at(0).catalog;
    const TilePlan plan = PlanTiles(TilingOptions{}, {catalog});
    EXPECT_EQ(plan.grid.tile_m, c.want_tile_m) << c.gsd_m;
    EXPECT_TRUE(plan.tile_side_automatic);
    // The nadir-most view's ground pixel: the nominal GSD stretched by at
    // most 1/cos(zenith) along one axis (SmallScene's views reach 30 deg).
    EXPECT_GE(plan.finest_gsd_m, 0.99 * c.gsd_m) << c.gsd_m;
    EXPECT_LE(plan.finest_gsd_m, 1.08 * c.gsd_m) << c.gsd_m;
    TilingOptions given;
    given.tile_m = 128;
    const TilePlan fixed = PlanTiles(given, {catalog});
    EXPECT_EQ(fixed.grid.tile_m, 128.0);
    EXPECT_FALSE(fixed.tile_side_automatic);
    std::printf("[figures] GSD %.1f m scene: finest image %.3f m, automatic tile %.0f m (%.0f px)\n", c.gsd_m,
                plan.finest_gsd_m, plan.grid.tile_m, plan.grid.tile_m / plan.finest_gsd_m);
  }
}

TEST(Synth, TruthFilesFollowTheJax068Conventions) {
  const Scene s = MakeScene(SmallScene());
  const fs::path ours = s.root / "Track3-Truth", jax = Dfc2019Root() / "Track3-Truth";
  // _DSM.txt: four numbers printed with six decimals, one per line.
  const std::regex line(R"(^-?\d+\.\d{6}$)");
  auto txt_lines = [](const fs::path& p) {
    std::vector<std::string> lines;
    std::ifstream in(p);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    return lines;
  };
  const auto ours_txt = txt_lines(ours / "SYN_001_DSM.txt");
  ASSERT_EQ(ours_txt.size(), 4u);
  for (const auto& l : ours_txt) EXPECT_TRUE(std::regex_match(l, line)) << l;
  const std::set<int> dfc_codes = {2, 5, 6, 9, 17, 65};
  auto check_rasters = [&](const fs::path& dir, const std::string& aoi) {
    const RasterInfo dsm = ReadRasterInfo((dir / (aoi + "_DSM.tif")).string());
    const RasterInfo cls = ReadRasterInfo((dir / (aoi + "_CLS.tif")).string());
    EXPECT_EQ(dsm.dtype, "Float32");
    EXPECT_EQ(cls.dtype, "Byte");
    EXPECT_EQ(dsm.bands, 1);
    EXPECT_EQ(dsm.width_px, dsm.height_px);
    EXPECT_EQ(cls.width_px, dsm.width_px);
    const FloatBand codes = ReadFloatBand((dir / (aoi + "_CLS.tif")).string());
    std::set<int> seen;
    for (float v : codes.values) seen.insert(static_cast<int>(v));
    for (int code : seen) EXPECT_TRUE(dfc_codes.count(code)) << aoi << " class " << code;
    return seen;
  };
  const std::set<int> ours_codes = check_rasters(ours, "SYN_001");
  for (int code : {2, 5, 6, 9, 17}) EXPECT_TRUE(ours_codes.count(code)) << "class " << code << " missing";
  if (fs::exists(jax)) {
    check_rasters(jax, "JAX_068");
    const auto jax_txt = txt_lines(jax / "JAX_068_DSM.txt");
    ASSERT_EQ(jax_txt.size(), 4u);
    for (const auto& l : jax_txt) EXPECT_TRUE(std::regex_match(l, line)) << l;
  }
  // Lower-left convention: DSM row 0 is the north edge, and the txt holds the
  // south-west corner. Every DSM pixel equals the scene height there.
  const DsmTxt grid = ParseDsmTxt(ReadTextFile((ours / "SYN_001_DSM.txt").string()), "txt");
  const FloatBand dsm = ReadFloatBand((ours / "SYN_001_DSM.tif").string());
  const double ul_northing = grid.northing_m + grid.size_px * grid.gsd_m;
  int mismatches = 0;
  for (int r = 0; r < dsm.height_px; ++r)
    for (int c = 0; c < dsm.width_px; ++c) {
      const double e = grid.easting_m + (c + 0.5) * grid.gsd_m, n = ul_northing - (r + 0.5) * grid.gsd_m;
      mismatches += dsm.values[static_cast<size_t>(r) * dsm.width_px + c] !=
                    s.result.city.HeightAt(e - s.result.utm_easting0_m, n - s.result.utm_northing0_m);
    }
  EXPECT_EQ(mismatches, 0);
}

TEST(Synth, SameSeedSameBytesOtherSeedOtherCity) {
  SynthOptions o = SmallScene();
  o.views = 2;
  o.size_m = 64;
  const Scene a = MakeScene(o);
  const std::string first = ReadTextFile(a.result.aois[0].views[1].path);
  const std::string dsm_a = ReadTextFile((a.root / "Track3-Truth" / "SYN_001_DSM.tif").string());
  const Scene b = MakeScene(o);  // same scratch folder name: rewritten in place
  EXPECT_EQ(ReadTextFile(b.result.aois[0].views[1].path), first);
  EXPECT_EQ(ReadTextFile((b.root / "Track3-Truth" / "SYN_001_DSM.tif").string()), dsm_a);
  o.seed = 8;
  const Scene c = MakeScene(o);
  EXPECT_NE(ReadTextFile((c.root / "Track3-Truth" / "SYN_001_DSM.tif").string()), dsm_a);
}

TEST(Synth, AdjacentBlocksShareTheirBoundary) {
  SynthOptions o = SmallScene();
  o.size_m = 64;
  o.views = 2;
  o.blocks_x = 2;
  const Scene s = MakeScene(o);
  ASSERT_EQ(s.result.aois.size(), 2u);
  EXPECT_EQ(s.result.aois[0].name, "SYN_001_X0Y0");
  EXPECT_EQ(s.result.aois[1].name, "SYN_001_X1Y0");
  const fs::path truth = s.root / "Track3-Truth";
  const DsmTxt west = ParseDsmTxt(ReadTextFile((truth / "SYN_001_X0Y0_DSM.txt").string()), "w");
  const DsmTxt east = ParseDsmTxt(ReadTextFile((truth / "SYN_001_X1Y0_DSM.txt").string()), "e");
  EXPECT_DOUBLE_EQ(east.easting_m, west.easting_m + 64.0);
  EXPECT_DOUBLE_EQ(east.northing_m, west.northing_m);
  NullProgress progress;
  EXPECT_EQ(RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress).NumIngested(), 2);
}

// East, north and up of an ENU frame at (lon, lat) in ECEF (geodetic normal).
Eigen::Matrix3d EnuFromEcef(const GeodeticPoint& g) {
  const double l = g.lon_deg * M_PI / 180, p = g.lat_deg * M_PI / 180;
  Eigen::Matrix3d m;
  m << -std::sin(l), std::cos(l), 0, -std::sin(p) * std::cos(l), -std::sin(p) * std::sin(l), std::cos(p),
      std::cos(p) * std::cos(l), std::cos(p) * std::sin(l), std::sin(p);
  return m;
}

// Truth views of an image's own camera, given in another ENU frame 2 km
// away, reproduce that image: same frame conversion, lighting and noise;
// only the cars (absent from truth views) differ.
TEST(Synth, TruthViewOfAnImagesCameraInAnotherFrameReproducesTheImage) {
  const SynthOptions o = SmallScene();
  const Scene scene = MakeScene(o);
  const int v = 2;
  const SynthView& view = scene.result.aois[0].views[v];
  const GeodeticPoint own = scene.result.enu_origin;
  const GeodeticPoint other{own.lon_deg + 0.02, own.lat_deg - 0.01, own.height_m + 30.0};
  const EnuFrame own_frame(own), other_frame(other);
  PinholeCamera cam;
  cam.fx = cam.fy = view.camera.focal_px;
  cam.cx = view.camera.principal_px.x();
  cam.cy = view.camera.principal_px.y();
  cam.width_px = view.camera.width_px;
  cam.height_px = view.camera.height_px;
  // Rotation between the frames from their ECEF axes (independent of the
  // finite differences the renderer uses).
  cam.cam_from_world_rotation = view.camera.cam_from_enu * EnuFromEcef(own) * EnuFromEcef(other).transpose();
  const Eigen::Vector3d centre_other = other_frame.EnuFromGeodetic(own_frame.GeodeticFromEnu(view.camera.centre_enu_m));
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * centre_other;
  const fs::path out = scene.root / "truth";
  NullProgress quiet;
  ASSERT_EQ(RenderTruthViews(o, {{"again", cam}}, other, v, out.string(), quiet), 1);
  const FloatImage truth = ReadFloatImage((out / "again.png").string());
  const FloatImage image = ReadFloatImage(view.path);
  const FloatBand mask = ReadFloatBand((out / "again_mask.png").string());
  ASSERT_EQ(truth.width_px, image.width_px);
  ASSERT_EQ(truth.height_px, image.height_px);
  std::size_t same = 0, inside = 0;
  const std::size_t n = static_cast<std::size_t>(truth.width_px) * truth.height_px;
  for (std::size_t p = 0; p < n; ++p) {
    bool equal = true;
    for (int c = 0; c < 3; ++c) equal = equal && std::abs(truth.values[3 * p + c] - image.values[3 * p + c]) <= 1.0f;
    same += equal;
    inside += mask.values[p] > 127;
  }
  // Cars cover ~2 % of the ground, with their shadows a few % of the pixels.
  EXPECT_GT(static_cast<double>(same) / n, 0.9);
  // The crop bounds the AOI's footprint, turned by the orbit's heading, plus
  // a margin: at a 30 deg turn the square fills about 1 / (cos + sin)^2 =
  // 54 % of its bounding box, less with the margin and the leaning buildings.
  EXPECT_GT(static_cast<double>(inside) / n, 0.3);
  EXPECT_LT(inside, n);
  EXPECT_THROW(RenderTruthViews(o, {{"again", cam}}, other, o.views, out.string(), quiet), Error);
}

TEST(Synth, OptionsAreChecked) {
  SynthOptions o;
  o.aoi = "no-number";
  EXPECT_THROW(o.Check(), Error);
  o = SynthOptions{};
  o.size_m = 100.25;  // not a whole number of 0.5 m pixels
  EXPECT_THROW(o.Check(), Error);
  o = SynthOptions{};
  o.views = 1;
  EXPECT_THROW(o.Check(), Error);
}

// Drawn scenes must each be a valid scene, made again from the same number,
// keep what is not drawn, and over many draws reach every part of the ranges
// DrawSceneOptions documents. The share bounds are wide (400 draws: a
// binomial share of 1/3 or 1/2 lies within +-0.1 with probability > 0.999).
TEST(Synth, DrawnScenesAreValidRepeatableAndSpanTheirRanges) {
  SynthOptions base;
  base.aoi = "DRW_007";
  base.size_m = 128;
  int one_band = 0, flat = 0, south = 0, tall = 0, few_views = 0, sixteen_bits = 0, oblique = 0;
  std::set<std::uint64_t> seeds;
  const int draws = 400;
  for (int d = 1; d <= draws; ++d) {
    const SynthOptions o = DrawSceneOptions(d, base);
    const SynthOptions again = DrawSceneOptions(d, base);
    EXPECT_EQ(o.seed, again.seed);
    EXPECT_EQ(o.lat_deg, again.lat_deg);
    EXPECT_EQ(o.max_building_m, again.max_building_m);
    EXPECT_NO_THROW(o.Check());
    EXPECT_EQ(o.aoi, "DRW_007");
    EXPECT_EQ(o.size_m, 128);
    EXPECT_EQ(o.gsd_m, base.gsd_m);
    EXPECT_GE(o.seed, 1000000u) << "drawn cities never reuse the small seeds the tuning cities have";
    seeds.insert(o.seed);
    EXPECT_LE(std::abs(o.lat_deg), 60.0);
    EXPECT_GE(o.min_off_nadir_deg, 0.0);
    EXPECT_LE(o.min_off_nadir_deg, 20.0);
    EXPECT_GE(o.max_off_nadir_deg, std::min(45.0, o.min_off_nadir_deg + 10.0) - 0.05);
    EXPECT_LE(o.max_off_nadir_deg, 45.0);
    EXPECT_GE(o.views, 3);
    EXPECT_LE(o.views, 16);
    EXPECT_LE(o.views_per_date, o.views);
    EXPECT_GE(o.max_building_m, 15.0);
    EXPECT_LE(o.max_building_m, 180.0);
    EXPECT_TRUE(o.relief_m == 0.0 || (o.relief_m >= 10.0 && o.relief_m <= 100.0)) << o.relief_m;
    EXPECT_GE(o.date_contrast, 0.5);
    EXPECT_LE(o.date_contrast, 3.0);
    one_band += o.bands == 1;
    flat += o.relief_m == 0.0;
    south += o.lat_deg < 0;
    tall += o.max_building_m >= 150.0;
    few_views += o.views <= 4;
    sixteen_bits += o.bit_depth == 16;
    oblique += o.min_off_nadir_deg >= 15.0;
  }
  EXPECT_EQ(seeds.size(), static_cast<std::size_t>(draws));
  EXPECT_NEAR(one_band / double(draws), 1.0 / 3.0, 0.1);
  EXPECT_NEAR(flat / double(draws), 0.5, 0.1);
  EXPECT_NEAR(south / double(draws), 0.5, 0.1);
  for (int count : {tall, few_views, sixteen_bits, oblique}) EXPECT_GT(count, draws / 20);
  EXPECT_NE(DrawSceneOptions(1, base).seed, DrawSceneOptions(2, base).seed);
}

}  // namespace
}  // namespace skyfall::synth
