#include "sfm/sfm.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <map>
#include <set>
#include <sstream>

#include "catalogs/aoi_catalog.h"
#include "core/error.h"
#include "dense/dense.h"
#include "sfm/bundle.h"
#include "sfm/export.h"
#include "testcity/testcity.h"
#include "tests/test_support.h"
#include "ingest/dfc2019.h"
#include "ingest/geo.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

// Issue targets on JAX_068.
constexpr double kTargetMedianAfterBaPx = 0.5;
constexpr double kTargetPinholeMaxPx = 0.05;

struct SyntheticAoi {
  fs::path root;
  synth::SynthResult scene;
  AoiCatalog catalog;
};

SyntheticAoi MakeSyntheticAoi(int views, const std::function<void(synth::SynthOptions&)>& adjust = {}) {
  SyntheticAoi s;
  s.root = ScratchDir("synth");
  synth::SynthOptions o;
  o.size_m = 128;
  o.views = views;
  o.seed = 3;
  if (adjust) adjust(o);
  NullProgress progress;
  s.scene = synth::RunSynth(o, s.root.string(), progress);
  const IngestResult ingest = RunIngest(IngestOptions{}, s.root.string(), (s.root / "catalogs").string(), progress);
  s.catalog = ingest.aois.at(0).catalog;
  return s;
}

// Scene-frame point -> geodetic, through the synthetic scene's UTM origin.
GeodeticPoint GeodeticOfScene(const synth::SynthResult& r, const Eigen::Vector3d& s) {
  const Eigen::Vector2d ll =
      GeodeticFromUtm(UtmZoneFromEpsg(r.epsg), r.utm_easting0_m + s.x(), r.utm_northing0_m + s.y());
  return {ll.x(), ll.y(), s.z()};
}

// BA offsets undo each image's RPC pointing bias (none, or the one synth
// wrote), the final cameras project like the true ones, and the tie points
// lie on the true surface. Bounds: 0.5 px for cameras (a tenth of the dense
// stage's matching window), 0.3 m median for points (0.6 px at 0.5 m GSD).
void ExpectCamerasAndSurfaceRecovered(const SyntheticAoi& s, const SfmResult& r, const char* label) {
  ASSERT_EQ(r.report.status, StageStatus::kOk) << r.report.message;
  EXPECT_EQ(r.report.metrics.at("num_images_used"), static_cast<double>(s.scene.aois[0].views.size()));
  EXPECT_LT(r.after.median_px, 0.3);
  EXPECT_GT(r.points.size(), 500u);
  const EnuFrame truth_frame(s.scene.enu_origin), sfm_frame(s.catalog.enu_origin);
  for (size_t i = 0; i < r.images.size(); ++i) {
    const synth::SynthView& truth = s.scene.aois[0].views[i];
    ASSERT_EQ(truth.name, r.images[i].name);
    // The RPC points at true + bias (the rotation adds under 0.1 px over a
    // 128 m crop at the biases tested): the offset brings it back.
    EXPECT_LT((r.images[i].ba_offset_px + truth.rpc_bias_shift_px).norm(), 0.5) << label << " " << truth.name;
    for (double fx : {0.1, 0.5, 0.9})
      for (double fy : {0.1, 0.5, 0.9}) {
        const double x = fx * 128, y = fy * 128;
        const GeodeticPoint g = GeodeticOfScene(s.scene, {x, y, s.scene.city.TerrainAt(x, y)});
        const Eigen::Vector2d want = truth.camera.Project(truth_frame.EnuFromGeodetic(g));
        const Eigen::Vector2d got = r.images[i].camera.Project(sfm_frame.EnuFromGeodetic(g));
        EXPECT_LT((got - want).norm(), 0.5) << label << " " << truth.name;
      }
  }
  std::vector<double> dz;
  for (const SfmPoint& p : r.points) {
    const GeodeticPoint g = sfm_frame.GeodeticFromEnu(p.enu_m);
    const Eigen::Vector2d en = UtmFromGeodetic(UtmZoneFromEpsg(s.scene.epsg), g.lon_deg, g.lat_deg);
    const double x = en.x() - s.scene.utm_easting0_m, y = en.y() - s.scene.utm_northing0_m;
    dz.push_back(std::abs(g.height_m - s.scene.city.HeightAt(x, y)));
  }
  std::sort(dz.begin(), dz.end());
  const double median_dz = dz[dz.size() / 2];
  const double within_1m = static_cast<double>(std::lower_bound(dz.begin(), dz.end(), 1.0) - dz.begin()) / dz.size();
  std::printf("[figures] %s SfM: %zu points, %d verified pairs, median |dz| %.3f m, %.1f%% within 1 m, "
              "reprojection median %.3f px\n",
              label, r.points.size(), r.verified_pairs, median_dz, 100 * within_1m, r.after.median_px);
  EXPECT_LT(median_dz, 0.3) << label;
  EXPECT_GT(within_1m, 0.8) << label;
}

TEST(Sfm, RecoversTheSyntheticCamerasAndSurface) {
  const SyntheticAoi s = MakeSyntheticAoi(6);
  NullProgress progress;
  ExpectCamerasAndSurfaceRecovered(s, RunSfm(SfmOptions{}, s.catalog, progress), "synthetic");
}

// The catalog's height range is ellipsoidal and the cameras live in ENU: at
// 4,000 m a verification that takes one for the other looks for the scene
// 4 km in the air and keeps no tie point.
TEST(Sfm, ACityAt4000MetresAboveTheEllipsoidGetsVerifiedTiePoints) {
  const SyntheticAoi s = MakeSyntheticAoi(6, [](synth::SynthOptions& o) { o.ground_height_m = 4000; });
  ASSERT_GT(s.catalog.min_ellipsoid_height_m, 3900);
  NullProgress progress;
  ExpectCamerasAndSurfaceRecovered(s, RunSfm(SfmOptions{}, s.catalog, progress), "4000 m");
}

// Vendor-like pointing biases (3 px shifts, 0.01 deg rotations) come out as
// the BA offsets; the absolute frame is the images' average.
TEST(Sfm, BiasedRpcsAreRecoveredByTheBundleOffsets) {
  const SyntheticAoi s = MakeSyntheticAoi(6, [](synth::SynthOptions& o) {
    o.rpc_bias_px = 3;
    o.rpc_bias_rotation_deg = 0.01;
  });
  double largest_px = 0;
  for (const auto& v : s.scene.aois[0].views) largest_px = std::max(largest_px, v.rpc_bias_shift_px.norm());
  ASSERT_GT(largest_px, 1.0);  // the biases are there to be recovered
  NullProgress progress;
  ExpectCamerasAndSurfaceRecovered(s, RunSfm(SfmOptions{}, s.catalog, progress), "biased RPCs");
}

// Two AOIs of a city hold different passes of the same biased acquisitions.
// Each bundle adjustment fixes its frame by the average of its images' RPCs,
// so without a shared gauge the two frames differ by their subsets' mean
// bias: the offsets of the acquisitions both hold disagree by pixels (metres
// on the ground, and more in height). Fixing both frames by the passes both
// hold makes their offsets agree.
TEST(Sfm, TilesHoldingDifferentPassesShareAFrameThroughTheirCommonAcquisitions) {
  const fs::path root = ScratchDir("synth_gauge");
  synth::SynthOptions o;
  o.size_m = 96;
  o.blocks_x = 2;
  o.views = 6;
  o.views_per_aoi = 4;  // two AOIs of 4 of 6 passes share 2 at least
  o.rpc_bias_px = 8;
  o.seed = 3;
  NullProgress progress;
  synth::RunSynth(o, root.string(), progress);
  const IngestResult ingest = RunIngest(IngestOptions{}, root.string(), (root / "catalogs").string(), progress);
  ASSERT_EQ(ingest.aois.size(), 2u);
  std::vector<AoiCatalog> catalogs = {ingest.aois[0].catalog, ingest.aois[1].catalog};
  std::set<std::string> first, common;
  for (const ImageRecord& im : catalogs[0].images) first.insert(im.acquisition_time);
  for (const ImageRecord& im : catalogs[1].images)
    if (first.count(im.acquisition_time)) common.insert(im.acquisition_time);
  ASSERT_GE(common.size(), 2u);
  ASSERT_LT(common.size(), 4u) << "the AOIs hold the same passes: nothing to show";

  // The largest disagreement between the two AOIs' offsets of a shared pass.
  auto disagreement_px = [&](bool gauge) {
    std::map<std::string, Eigen::Vector2d> offsets;
    double worst = 0;
    for (AoiCatalog c : catalogs) {
      if (gauge) c.gauge_acquisitions.assign(common.begin(), common.end());
      const SfmResult r = RunSfm(SfmOptions{}, c, progress);
      EXPECT_EQ(r.report.status, StageStatus::kOk) << r.report.message;
      EXPECT_EQ(r.absolute_position.find("acquisitions every tile") != std::string::npos, gauge) << r.absolute_position;
      for (const SfmImage& im : r.images) {
        if (!common.count(im.acquisition_time)) continue;
        const auto [it, first_seen] = offsets.emplace(im.acquisition_time, im.ba_offset_px);
        if (!first_seen) worst = std::max(worst, (it->second - im.ba_offset_px).norm());
      }
    }
    return worst;
  };
  const double own_frames_px = disagreement_px(false), shared_frame_px = disagreement_px(true);
  RecordProperty("own_frames_px", std::to_string(own_frames_px));
  RecordProperty("shared_frame_px", std::to_string(shared_frame_px));
  // Without the gauge the subsets' mean biases differ by pixels here; with it
  // the offsets agree to the tie points' noise (0.3 px: half a dense cell's
  // worth of a pixel, well under the bias).
  EXPECT_GT(own_frames_px, 1.0);
  EXPECT_LT(shared_frame_px, 0.3);
}

// A satellite-like camera 600 km away looking at the origin from `from`
// (a unit direction), 0.5 m pixels.
PinholeCamera FarCamera(const Eigen::Vector3d& from) {
  PinholeCamera c;
  const Eigen::Vector3d centre = 600e3 * from.normalized();
  const Eigen::Vector3d z = -centre.normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();  // no view is straight down here
  const Eigen::Vector3d y = z.cross(x);
  c.cam_from_world_rotation.row(0) = x;
  c.cam_from_world_rotation.row(1) = y;
  c.cam_from_world_rotation.row(2) = z;
  c.cam_from_world_translation = -c.cam_from_world_rotation * centre;
  c.fx = c.fy = 600e3 / 0.5;
  c.cx = c.cy = 500;
  c.width_px = c.height_px = 1000;
  return c;
}

// The gauge move leaves every reprojection as it was and puts the gauge
// images' offsets at their least-squares average (sum P_i^T o_i = 0).
TEST(Bundle, TheGaugeMoveKeepsTheResidualsAndCentresTheGaugeImagesOffsets) {
  BundleProblem bp;
  bp.cameras = {FarCamera({0.3, 0.1, 1}), FarCamera({-0.25, 0.2, 1}), FarCamera({0.05, -0.35, 1})};
  bp.offsets_px = {{3.0, -2.0}, {-1.5, 4.0}, {0.7, 0.2}};
  bp.image_used = {true, true, true};
  bp.gauge_image = {true, true, false};
  for (double x : {-80.0, 0.0, 90.0})
    for (double y : {-70.0, 10.0, 60.0}) {
      bp.points.push_back({x, y, 0.1 * x});
      std::vector<Observation> track;
      for (int i = 0; i < 3; ++i) {
        Observation o;
        o.image = i;
        o.pixel = bp.cameras[i].Project(bp.points.back()) + bp.offsets_px[i] + Eigen::Vector2d(0.01 * i, -0.02);
        track.push_back(o);
      }
      bp.tracks.push_back(track);
    }
  const std::vector<double> before = ReprojectionErrors(bp);
  const double moved_m = MoveToGaugeAverage(&bp);
  EXPECT_GT(moved_m, 1.0);  // offsets of pixels: metres on the ground
  const std::vector<double> after = ReprojectionErrors(bp);
  ASSERT_EQ(before.size(), after.size());
  // A pinhole is affine to a few parts in 1e4 over a scene 200 m deep in
  // range at 600 km: of the move's 10-20 px, 2e-3 px.
  for (std::size_t k = 0; k < before.size(); ++k) EXPECT_NEAR(after[k], before[k], 2e-3) << k;
  Eigen::Vector3d balance = Eigen::Vector3d::Zero();
  for (int i = 0; i < 2; ++i) {
    Eigen::Matrix<double, 2, 3> j;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d h = Eigen::Vector3d::Unit(k);
      j.col(k) = 0.5 * (bp.cameras[i].Project(h) - bp.cameras[i].Project(-h));
    }
    balance += j.transpose() * bp.offsets_px[i];
  }
  // 1e-4: the move takes its Jacobians at the points' centre, these at the
  // origin 3 m away; at 600 km they differ by a few parts in 1e7 of sum P^T o (about 10).
  EXPECT_LT(balance.norm(), 1e-4);
  EXPECT_LT(MoveToGaugeAverage(&bp), 1e-6);  // already there
}

TEST(Sfm, DenseHeightsFollowTheSyntheticSurface) {
  const SyntheticAoi s = MakeSyntheticAoi(6);
  NullProgress progress;
  const SfmResult sfm = RunSfm(SfmOptions{}, s.catalog, progress);
  ASSERT_EQ(sfm.report.status, StageStatus::kOk) << sfm.report.message;
  std::vector<DenseView> views;
  for (const SfmImage& im : sfm.images) {
    DenseView v;
    v.name = im.name;
    v.camera = im.camera;
    FloatImage pixels = ReadFloatImage(im.path);
    v.width_px = pixels.width_px;
    v.height_px = pixels.height_px;
    v.bands = pixels.bands;
    v.pixels = std::move(pixels.values);
    views.push_back(std::move(v));
  }
  std::vector<DensePair> pairs;
  for (const PairStats& p : sfm.pairs) pairs.push_back({p.a, p.b, p.verified});
  std::vector<Eigen::Vector3d> points;
  for (const SfmPoint& p : sfm.points) points.push_back(p.enu_m);
  // Error of the measured (not filled) cells over the AOI (the grid spans
  // the tie points, which reach beyond it into the image margins that fewer
  // views see).
  const EnuFrame frame(s.catalog.enu_origin);
  struct Figures {
    double valid = 0, median_dz = 0, within_1m = 0, seconds = 0;
    double mean_dz_all = 0;  // over every AOI cell with a height, filled ones included
  };
  auto measure = [&](const DenseOptions& options) {
    const DenseResult r = RunDenseHeights(options, views, pairs, points, progress);
    EXPECT_EQ(r.report.status, StageStatus::kOk) << r.report.message;
    const HeightGrid& g = r.grid;
    std::vector<double> dz;
    std::size_t aoi_cells = 0, with_height = 0;
    double sum_all = 0;
    for (int j = 0; j < g.ny; ++j)
      for (int i = 0; i < g.nx; ++i) {
        const float h = g.height_m[g.Index(i, j)];
        const GeodeticPoint geo =
            frame.GeodeticFromEnu({g.x0_m + i * g.cell_m, g.y0_m + j * g.cell_m, std::isfinite(h) ? h : 0.0});
        const Eigen::Vector2d en = UtmFromGeodetic(UtmZoneFromEpsg(s.scene.epsg), geo.lon_deg, geo.lat_deg);
        const double x = en.x() - s.scene.utm_easting0_m, y = en.y() - s.scene.utm_northing0_m;
        if (x < 0 || y < 0 || x > 128 || y > 128) continue;
        ++aoi_cells;
        if (!std::isfinite(h)) continue;
        const double e = std::abs(geo.height_m - s.scene.city.HeightAt(x, y));
        sum_all += e;
        ++with_height;
        if (!g.filled[g.Index(i, j)]) dz.push_back(e);
      }
    std::sort(dz.begin(), dz.end());
    Figures f;
    f.valid = static_cast<double>(dz.size()) / static_cast<double>(aoi_cells);
    f.median_dz = dz.at(dz.size() / 2);
    f.within_1m = static_cast<double>(std::lower_bound(dz.begin(), dz.end(), 1.0) - dz.begin()) / dz.size();
    f.seconds = r.report.seconds;
    f.mean_dz_all = sum_all / static_cast<double>(with_height);
    std::printf("[figures] synthetic dense heights (visibility pass %s): %d x %d cells, %.0f pairs, %.1f%% of the AOI "
                "with a height, median |dz| %.3f m, %.1f%% within 1 m; mean |dz| with filled cells %.3f m; %.1f s\n",
                options.visibility.pass ? "on" : "off", g.nx, g.ny, r.report.metrics.at("pairs"), 100 * f.valid,
                f.median_dz, 100 * f.within_1m, f.mean_dz_all, f.seconds);
    return f;
  };
  const Figures with = measure(DenseOptions{});
  DenseOptions one_pass;
  one_pass.visibility.pass = false;
  const Figures without = measure(one_pass);
  // Tolerances: a height step is 0.25 m and the truth is sampled at the cell
  // centre while the cell's window spans 2.5 m, so walls blur over a window;
  // tie points already reach median 0.3 m (RecoversTheSyntheticCamerasAndSurface).
  // Coverage: cells beside walls are hidden from most of the 6 views and
  // flat roofs give NCC nothing to correlate, so they are left to the fill
  // (measured 72% with one pass, 71% with the visibility pass). With only 6
  // views the visibility pass barely helps here (median |dz| 0.062 -> 0.059 m,
  // mean with filled cells 1.60 -> 1.70 m); on JAX_068's 19 views it clearly
  // helps (decision D-020).
  EXPECT_LT(with.median_dz, 0.3);
  EXPECT_GT(with.within_1m, 0.85);
  EXPECT_GT(with.valid, 0.6);
  EXPECT_LT(without.median_dz, 0.3);
  EXPECT_GT(without.within_1m, 0.85);
}

TEST(Sfm, Jax068MeetsTheTargets) {
  SKYFALL_REQUIRE_DFC2019();
  const fs::path dir = ScratchDir("jax");
  NullProgress progress;
  const IngestResult ingest = RunIngest(IngestOptions{}, Dfc2019Root().string(), dir.string(), progress);
  const SfmResult r = RunSfm(SfmOptions{}, ingest.aois.at(0).catalog, progress);
  ASSERT_EQ(r.report.status, StageStatus::kOk) << r.report.message;
  const auto& m = r.report.metrics;
  std::printf("[figures] JAX_068 SfM: %g images, %g points; pinhole max %.4f px mean %.4f px; reprojection "
              "median %.3f -> %.3f px, mean %.3f -> %.3f px, p90 %.3f -> %.3f px; %.1f s\n",
              m.at("num_images_used"), m.at("num_points"), m.at("dlt_max_error_px"), m.at("dlt_mean_error_px"),
              r.before.median_px, r.after.median_px, r.before.mean_px, r.after.mean_px, r.before.p90_px,
              r.after.p90_px, r.report.seconds);
  EXPECT_LE(m.at("dlt_max_error_px"), kTargetPinholeMaxPx);
  EXPECT_LE(r.after.median_px, kTargetMedianAfterBaPx);
  EXPECT_LT(r.after.median_px, r.before.median_px);
  EXPECT_EQ(m.at("num_images_used"), 19);
  EXPECT_GT(m.at("num_points"), 1000);
}

// sfm.anchor_image: one image's RPC taken as exact instead of the average.
TEST(Sfm, AnAnchorImageHoldsItsRpcAndATileWithoutItFallsBackToTheAverage) {
  const SyntheticAoi s = MakeSyntheticAoi(4, [](synth::SynthOptions& o) { o.rpc_bias_px = 3; });
  NullProgress progress;
  SfmOptions o;
  o.anchor_image = s.catalog.images[2].name;
  const SfmResult r = RunSfm(o, s.catalog, progress);
  ASSERT_EQ(r.report.status, StageStatus::kOk) << r.report.message;
  EXPECT_EQ(r.images[2].ba_offset_px, Eigen::Vector2d::Zero());
  EXPECT_EQ(r.absolute_position, "the RPC of " + o.anchor_image + " (sfm.anchor_image)");
  // The others move relative to it: their biases differ from the anchor's.
  EXPECT_GT(r.images[0].ba_offset_px.norm() + r.images[1].ba_offset_px.norm(), 0.5);
  const SfmResult average = RunSfm(SfmOptions{}, s.catalog, progress);
  EXPECT_EQ(average.absolute_position, "the average of 4 images' RPCs");
  // A tile that the anchor image does not cover falls back to the average
  // and says so, naming the images it has.
  o.anchor_image = "NOT_AN_IMAGE";
  const SfmResult fallback = RunSfm(o, s.catalog, progress);
  ASSERT_EQ(fallback.report.status, StageStatus::kOk) << fallback.report.message;
  EXPECT_EQ(fallback.absolute_position, "the average of 4 images' RPCs");
  ASSERT_FALSE(fallback.report.warnings.empty());
  EXPECT_NE(fallback.report.warnings[0].find("NOT_AN_IMAGE"), std::string::npos) << fallback.report.warnings[0];
  EXPECT_NE(fallback.report.warnings[0].find(s.catalog.images[0].name), std::string::npos);
}

// A second real AOI, from another sensor, as a user brings it: three 16-bit
// panchromatic Pleiades crops with RPC tags, 81-275 m above the ellipsoid.
TEST(Sfm, PleiadesTripletIsIngestedAndGetsTiePoints) {
  SKYFALL_REQUIRE_PLEIADES_MRS();
  const fs::path dir = ScratchDir("mrs");
  NullProgress progress;
  const IngestResult ingest = RunIngest(IngestOptions{}, PleiadesMrsRoot().string(), dir.string(), progress);
  ASSERT_EQ(ingest.aois.size(), 1u);
  const AoiCatalog& c = ingest.aois[0].catalog;
  ASSERT_EQ(c.images.size(), 3u);
  EXPECT_EQ(c.images[0].dtype, "UInt16");
  ASSERT_TRUE(c.truth.has_value());
  EXPECT_EQ(c.truth->epsg, 32631);
  // The scene's height range: s2p's DSM spans about 81-275 m above the ellipsoid.
  EXPECT_LT(c.min_ellipsoid_height_m, 90);
  EXPECT_GT(c.max_ellipsoid_height_m, 260);
  const SfmResult r = RunSfm(SfmOptions{}, c, progress);
  ASSERT_EQ(r.report.status, StageStatus::kOk) << r.report.message;
  std::printf("[figures] pleiades-mrs SfM: %zu points, %d verified pairs, reprojection median %.3f -> %.3f px, "
              "largest BA offset %.2f px\n",
              r.points.size(), r.verified_pairs, r.before.median_px, r.after.median_px,
              r.report.metrics.at("ba_largest_offset_px"));
  EXPECT_EQ(r.report.metrics.at("num_images_used"), 3);
  EXPECT_EQ(r.verified_pairs, 3);
  EXPECT_GT(r.points.size(), 500u);
  EXPECT_LE(r.after.median_px, kTargetMedianAfterBaPx);
}

TEST(Sfm, ImageWithoutMatchesIsLeftOutAndOneImageIsDegenerate) {
  SyntheticAoi s = MakeSyntheticAoi(3);
  // Image 3 becomes a featureless grey raster with the same camera.
  ImageRecord& blank = s.catalog.images[2];
  const fs::path blank_path = s.root / "blank.tif";
  std::vector<std::uint8_t> grey(static_cast<size_t>(blank.width_px) * blank.height_px * 3, 120);
  WriteByteTiff(blank_path.string(), blank.width_px, blank.height_px, 3, grey.data());
  blank.path = blank_path.string();
  NullProgress progress;
  const SfmResult r = RunSfm(SfmOptions{}, s.catalog, progress);
  EXPECT_EQ(r.report.status, StageStatus::kOk) << r.report.message;
  EXPECT_FALSE(r.images[2].used);
  EXPECT_NE(r.images[2].status.find("left out"), std::string::npos) << r.images[2].status;
  // The image left out, and what the two left (a stereo pair) cannot do.
  ASSERT_EQ(r.report.warnings.size(), 2u);
  EXPECT_NE(r.report.warnings[0].find(r.images[2].name), std::string::npos);
  EXPECT_NE(r.report.warnings[1].find("stereo pair"), std::string::npos) << r.report.warnings[1];

  AoiCatalog single = s.catalog;
  single.images.resize(1);
  const SfmResult one = RunSfm(SfmOptions{}, single, progress);
  EXPECT_EQ(one.report.status, StageStatus::kDegenerate);
  EXPECT_NE(one.report.message.find("at least 2 images"), std::string::npos) << one.report.message;
}

// Reads a COLMAP text file without its comment lines.
std::vector<std::string> DataLines(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> out;
  for (std::string line; std::getline(in, line);)
    if (line.empty() || line[0] != '#') out.push_back(line);
  return out;
}

TEST(Sfm, ColmapExportReprojectsWithColmapConventions) {
  const SyntheticAoi s = MakeSyntheticAoi(3);
  NullProgress progress;
  const SfmResult r = RunSfm(SfmOptions{}, s.catalog, progress);
  ASSERT_EQ(r.report.status, StageStatus::kOk);
  const fs::path out = s.root / "sfm";
  WriteSfmOutputs(r, s.catalog, out.string());
  for (const char* f : {"cameras.json", "points.ply", "sfm_report.json", "colmap/cameras.txt"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  // Each image's sun from the catalog travels on to training (held-out
  // views choose their appearance by it).
  const nlohmann::json cameras = nlohmann::json::parse(std::ifstream(out / "cameras.json"));
  ASSERT_EQ(cameras.at("images").size(), s.catalog.images.size());
  for (std::size_t k = 0; k < s.catalog.images.size(); ++k) {
    ASSERT_TRUE(s.catalog.images[k].sun_elevation_deg.has_value());
    EXPECT_DOUBLE_EQ(cameras["images"][k].at("sun_elevation_deg").get<double>(), *s.catalog.images[k].sun_elevation_deg);
    EXPECT_DOUBLE_EQ(cameras["images"][k].at("sun_azimuth_deg").get<double>(), *s.catalog.images[k].sun_azimuth_deg);
  }

  // cameras.txt: id PINHOLE w h fx fy cx cy
  std::map<int, Eigen::Vector4d> intrinsics;
  for (const auto& line : DataLines(out / "colmap" / "cameras.txt")) {
    std::istringstream in(line);
    int id, w, h;
    std::string model;
    Eigen::Vector4d k;
    in >> id >> model >> w >> h >> k[0] >> k[1] >> k[2] >> k[3];
    EXPECT_EQ(model, "PINHOLE");
    intrinsics[id] = k;
  }
  std::map<int, std::vector<Eigen::Vector3d>> points;  // id -> xyz
  for (const auto& line : DataLines(out / "colmap" / "points3D.txt")) {
    std::istringstream in(line);
    int id;
    Eigen::Vector3d X;
    in >> id >> X.x() >> X.y() >> X.z();
    points[id] = {X};
  }
  ASSERT_EQ(points.size(), r.points.size());
  const auto images = DataLines(out / "colmap" / "images.txt");
  ASSERT_EQ(images.size(), 6u);  // two lines per image
  double worst = 0;
  for (size_t i = 0; i < images.size(); i += 2) {
    std::istringstream head(images[i]);
    int id, cam;
    double qw, qx, qy, qz;
    Eigen::Vector3d t;
    std::string name;
    head >> id >> qw >> qx >> qy >> qz >> t.x() >> t.y() >> t.z() >> cam >> name;
    EXPECT_TRUE(fs::exists(out / "colmap" / "images" / name)) << name;
    const Eigen::Matrix3d R = Eigen::Quaterniond(qw, qx, qy, qz).toRotationMatrix();
    const Eigen::Vector4d k = intrinsics.at(cam);
    std::istringstream obs(images[i + 1]);
    double x, y;
    int pid;
    int n = 0;
    while (obs >> x >> y >> pid) {
      const Eigen::Vector3d c = R * points.at(pid)[0] + t;
      const Eigen::Vector2d proj(k[0] * c.x() / c.z() + k[2], k[1] * c.y() / c.z() + k[3]);
      worst = std::max(worst, (proj - Eigen::Vector2d(x, y)).norm());
      ++n;
    }
    EXPECT_GT(n, 50);
  }
  // Every observation survived the BA outlier cut, so it reprojects within it.
  EXPECT_LT(worst, SfmOptions{}.max_reprojection_after_ba_px);
  std::ifstream ply(out / "points.ply");
  std::string header((std::istreambuf_iterator<char>(ply)), std::istreambuf_iterator<char>());
  EXPECT_NE(header.find("element vertex " + std::to_string(r.points.size())), std::string::npos);
}

}  // namespace
}  // namespace skyfall
