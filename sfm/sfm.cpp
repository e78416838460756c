#include "sfm/sfm.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <numeric>
#include <set>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/format.h"
#include "ingest/geo.h"
#include "ingest/radiometry.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

struct Loaded {
  std::vector<ImageFeatures> features;
  std::vector<PinholeCamera> cameras;
};

// Tracks triangulated with the current cameras and kept if they pass the
// reprojection and angle filters; `errors_px` receives their residuals.
void TriangulateTracks(const std::vector<std::vector<Observation>>& tracks, const std::vector<PinholeCamera>& cameras,
                       const SfmOptions& o, BundleProblem* bp) {
  bp->tracks.clear();
  bp->points.clear();
  for (const auto& track : tracks) {
    const Eigen::Vector3d X = Triangulate(cameras, track);
    if (!X.allFinite()) continue;
    bool ok = true;
    for (const auto& obs : track) {
      ok = ok && cameras[obs.image].Depth(X) > 0 &&
           (cameras[obs.image].Project(X) - obs.pixel).norm() <= o.max_reprojection_before_ba_px;
    }
    if (!ok || MaxTriangulationAngleDeg(cameras, track, X) < o.min_triangulation_angle_deg) continue;
    bp->tracks.push_back(track);
    bp->points.push_back(X);
  }
}

// Drops observations of unused images and tracks left with fewer than two.
void KeepUsedImages(BundleProblem* bp) {
  std::vector<std::vector<Observation>> tracks;
  std::vector<Eigen::Vector3d> points;
  for (size_t t = 0; t < bp->tracks.size(); ++t) {
    std::vector<Observation> kept;
    for (const auto& o : bp->tracks[t])
      if (bp->image_used[o.image]) kept.push_back(o);
    if (kept.size() >= 2) {
      tracks.push_back(kept);
      points.push_back(bp->points[t]);
    }
  }
  bp->tracks = std::move(tracks);
  bp->points = std::move(points);
}

// Removes observations whose residual exceeds `max_px`.
void CutOutliers(BundleProblem* bp, double max_px) {
  for (size_t t = 0; t < bp->tracks.size(); ++t) {
    auto& track = bp->tracks[t];
    track.erase(std::remove_if(track.begin(), track.end(),
                               [&](const Observation& o) {
                                 const Eigen::Vector2d p = bp->cameras[o.image].Project(bp->points[t]) + bp->offsets_px[o.image];
                                 return (p - o.pixel).norm() > max_px;
                               }),
                track.end());
  }
  KeepUsedImages(bp);
}

// The index of the anchor image named by the option, -1 for none or when
// this catalog (a tile that the image does not cover) lacks it; `warnings`
// then says so, naming the images it has.
int AnchorIndex(const std::string& name, const std::vector<SfmImage>& images, const std::string& aoi,
                std::vector<std::string>* warnings) {
  if (name.empty()) return -1;
  std::string names;
  for (size_t i = 0; i < images.size(); ++i) {
    if (images[i].name == name) return static_cast<int>(i);
    names += (names.empty() ? "" : ", ") + images[i].name;
  }
  warnings->push_back("sfm " + aoi + ": sfm.anchor_image '" + name + "' is not an image here (" + names +
                      "); the absolute position is the images' average");
  return -1;
}

}  // namespace

void SfmOptions::Check() const {
  CheckOptionRanges(*this, "sfm");
  features.Check();  // what involves two of its fields
}

ReprojectionStats ComputeStats(std::vector<double> e) {
  ReprojectionStats s;
  s.count = static_cast<int>(e.size());
  if (e.empty()) return s;
  std::sort(e.begin(), e.end());
  s.median_px = e[e.size() / 2];
  s.p90_px = e[std::min(e.size() - 1, static_cast<size_t>(0.9 * e.size()))];
  s.mean_px = std::accumulate(e.begin(), e.end(), 0.0) / static_cast<double>(e.size());
  return s;
}

namespace {

// 1. Cameras (the RPC approximated by a pinhole) and features per image.
Loaded LoadImages(const SfmOptions& options, const AoiCatalog& catalog, Progress& progress, SfmResult* result) {
  const EnuFrame frame(catalog.enu_origin);
  const auto enu = [&frame](const GeodeticPoint& g) { return frame.EnuFromGeodetic(g); };
  const int n = static_cast<int>(catalog.images.size());
  Loaded loaded;
  progress.Begin("sfm cameras+features " + catalog.aoi, n);
  for (int i = 0; i < n; ++i) {
    const ImageRecord& rec = catalog.images[i];
    SfmImage im;
    im.name = rec.name;
    im.path = rec.path;
    im.acquisition_time = rec.acquisition_time;
    im.sun_elevation_deg = rec.sun_elevation_deg;
    im.sun_azimuth_deg = rec.sun_azimuth_deg;
    im.radiometry = rec.radiometry;
    im.approximation = ApproximateRpcByPinhole(rec.rpc, rec.width_px, rec.height_px,
                                               EllipsoidHeightM(catalog.min_ellipsoid_height_m),
                                               EllipsoidHeightM(catalog.max_ellipsoid_height_m), enu, options.pinhole);
    im.camera = im.approximation.camera;
    NormalizedImage pixels = ReadNormalizedImage(rec.path, rec.radiometry);
    for (float& v : pixels.rgb) v *= 255.0f;  // keypoint colours are 8-bit
    loaded.features.push_back(
        DetectFeatures(pixels.rgb, pixels.width_px, pixels.height_px, 3, options.features, &pixels.valid));
    im.keypoints = static_cast<int>(loaded.features.back().keypoints.size());
    loaded.cameras.push_back(im.camera);
    result->images.push_back(im);
    progress.Advance(i + 1, rec.name);
  }
  progress.End();
  return loaded;
}

// The image pairs with enough verified matches, and those matches.
struct VerifiedPairs {
  std::vector<std::pair<int, int>> pairs;
  std::vector<std::vector<std::pair<int, int>>> matches;
};

// 2. Pairwise matching and verification, pairs in parallel; results are
// collected by pair index so the outcome does not depend on scheduling.
VerifiedPairs MatchPairs(const SfmOptions& options, const AoiCatalog& catalog, const Loaded& loaded,
                         Progress& progress, SfmResult* result) {
  const int n = static_cast<int>(catalog.images.size());
  VerifyOptions verify = options.verify;
  verify.min_up = EnuUpAtOrigin(EllipsoidHeightM(catalog.min_ellipsoid_height_m), catalog.enu_origin);
  verify.max_up = EnuUpAtOrigin(EllipsoidHeightM(catalog.max_ellipsoid_height_m), catalog.enu_origin);
  std::vector<std::pair<int, int>> all_pairs;
  for (int a = 0; a < n; ++a)
    for (int b = a + 1; b < n; ++b) all_pairs.emplace_back(a, b);
  std::vector<std::vector<std::pair<int, int>>> verified(all_pairs.size());
  std::vector<int> ratio_counts(all_pairs.size(), 0);
  progress.Begin("sfm matching " + catalog.aoi, all_pairs.size());
  std::mutex progress_mutex;
  std::size_t done = 0;
  tbb::parallel_for(std::size_t{0}, all_pairs.size(), [&](std::size_t k) {
    const auto [a, b] = all_pairs[k];
    const auto raw = MatchFeatures(loaded.features[a], loaded.features[b], options.features.ratio);
    ratio_counts[k] = static_cast<int>(raw.size());
    verified[k] = VerifyMatches(loaded.cameras[a], loaded.cameras[b], loaded.features[a].keypoints,
                                loaded.features[b].keypoints, raw, verify);
    const std::lock_guard<std::mutex> lock(progress_mutex);
    progress.Advance(++done, result->images[a].name + " x " + result->images[b].name);
  });
  progress.End();
  VerifiedPairs kept;
  for (std::size_t k = 0; k < all_pairs.size(); ++k) {
    const auto [a, b] = all_pairs[k];
    result->pairs.push_back({a, b, ratio_counts[k], static_cast<int>(verified[k].size())});
    if (static_cast<int>(verified[k].size()) >= options.min_matches_per_pair) {
      kept.pairs.emplace_back(a, b);
      kept.matches.push_back(std::move(verified[k]));
    }
  }
  result->verified_pairs = static_cast<int>(kept.pairs.size());
  return kept;
}

// The images whose RPCs' average fixes the frame: those of the city's gauge
// acquisitions (AoiCatalog::gauge_acquisitions) that BA uses, when there are
// two at least (one fixes no height); empty, meaning every image, otherwise.
std::vector<bool> GaugeImages(const AoiCatalog& catalog, const BundleProblem& bp, SfmResult* result) {
  if (catalog.gauge_acquisitions.empty()) return {};
  const std::set<std::string> gauge(catalog.gauge_acquisitions.begin(), catalog.gauge_acquisitions.end());
  std::vector<bool> on(bp.image_used.size(), false);
  int count = 0;
  for (std::size_t i = 0; i < on.size(); ++i) {
    on[i] = bp.image_used[i] && gauge.count(result->images[i].acquisition_time) > 0;
    count += on[i];
  }
  if (count >= 2) return on;
  result->report.warnings.push_back(fmt::format(
      "sfm {}: {} of the {} acquisitions that fix the city's frame are used here; the frame is the average of all "
      "its images instead, and may differ from its neighbours'",
      catalog.aoi, count, gauge.size()));
  return {};
}

// 3-4. Tracks triangulated with the RPC cameras; images with too few
// observations are left out. Returns how many images are used.
int BuildBundleProblem(const SfmOptions& options, const AoiCatalog& catalog, const Loaded& loaded,
                       const VerifiedPairs& verified, BundleProblem* bp, SfmResult* result) {
  const int n = static_cast<int>(catalog.images.size());
  std::vector<std::vector<Eigen::Vector2d>> keypoints;
  for (const auto& f : loaded.features) keypoints.push_back(f.keypoints);
  const auto tracks = BuildTracks(verified.pairs, verified.matches, keypoints);
  bp->cameras = loaded.cameras;
  bp->offsets_px.assign(n, Eigen::Vector2d::Zero());
  bp->image_used.assign(n, true);
  bp->anchor_image = AnchorIndex(options.anchor_image, result->images, catalog.aoi, &result->report.warnings);
  TriangulateTracks(tracks, loaded.cameras, options, bp);
  std::vector<int> observations(n, 0);
  for (const auto& t : bp->tracks)
    for (const auto& o : t) ++observations[o.image];
  int used = 0;
  for (int i = 0; i < n; ++i) {
    bp->image_used[i] = observations[i] >= options.min_observations_per_image;
    used += bp->image_used[i];
    if (!bp->image_used[i]) {
      result->images[i].status = "left out: " + std::to_string(observations[i]) + " observations (minimum " +
                                 std::to_string(options.min_observations_per_image) + ")";
      result->report.warnings.push_back(result->images[i].name + ": " + result->images[i].status);
    }
  }
  KeepUsedImages(bp);
  bp->gauge_image = GaugeImages(catalog, *bp, result);
  return used;
}

// 6. Products: coloured points with their mean residual, and each image's
// BA offset folded into its principal point.
void CollectProducts(const BundleProblem& bp, const Loaded& loaded, SfmResult* result) {
  std::vector<int> observations(result->images.size(), 0);
  for (size_t t = 0; t < bp.tracks.size(); ++t) {
    SfmPoint p;
    p.enu_m = bp.points[t];
    p.track = bp.tracks[t];
    Eigen::Vector3d rgb = Eigen::Vector3d::Zero();
    double err = 0;
    for (const auto& o : p.track) {
      ++observations[o.image];
      const auto& c = loaded.features[o.image].colours[o.keypoint];
      rgb += Eigen::Vector3d(c[0], c[1], c[2]);
      err += (bp.cameras[o.image].Project(p.enu_m) + bp.offsets_px[o.image] - o.pixel).norm();
    }
    rgb /= static_cast<double>(p.track.size());
    for (int k = 0; k < 3; ++k) p.rgb[k] = static_cast<std::uint8_t>(std::lround(rgb[k]));
    p.reprojection_error_px = err / static_cast<double>(p.track.size());
    result->points.push_back(std::move(p));
  }
  for (std::size_t i = 0; i < result->images.size(); ++i) {
    SfmImage& im = result->images[i];
    im.observations = observations[i];
    im.used = bp.image_used[i] && observations[i] > 0;
    if (!im.used && im.status.empty()) im.status = "left out: no observation survived bundle adjustment";
    if (im.used) im.status = "ok";
    im.ba_offset_px = bp.offsets_px[i];
    im.camera.cx += im.ba_offset_px.x();
    im.camera.cy += im.ba_offset_px.y();
  }
}

// The report: fit and residual figures, what fixed the absolute position,
// and what a stereo pair cannot do. Returns how many images are used.
int ReportSfm(const SfmOptions& options, const AoiCatalog& catalog, const BundleProblem& bp, Progress& progress,
              SfmResult* result) {
  int images_used = 0;
  double dlt_max = 0, dlt_mean_sum = 0, largest_offset_px = 0;
  Eigen::Vector2d mean_offset_px = Eigen::Vector2d::Zero();
  for (const auto& im : result->images) {
    images_used += im.used;
    dlt_max = std::max(dlt_max, im.approximation.max_error_px);
    dlt_mean_sum += im.approximation.mean_error_px;
    if (!im.used) continue;
    mean_offset_px += im.ba_offset_px;
    largest_offset_px = std::max(largest_offset_px, im.ba_offset_px.norm());
  }
  if (images_used > 0) mean_offset_px /= images_used;
  auto& m = result->report.metrics;
  m["dlt_max_error_px"] = dlt_max;
  m["dlt_mean_error_px"] = dlt_mean_sum / static_cast<int>(result->images.size());
  m["ba_median_reproj_px_before"] = result->before.median_px;
  m["ba_median_reproj_px_after"] = result->after.median_px;
  m["num_points"] = static_cast<double>(result->points.size());
  m["num_images_used"] = images_used;
  // The gauge: a shift common to every image is invisible to tie points, so
  // the absolute position is the robust average of the images' RPCs (the
  // Cauchy prior on each offset). These say how far BA moved them from it.
  m["ba_mean_offset_px"] = mean_offset_px.norm();
  m["ba_largest_offset_px"] = largest_offset_px;
  const bool anchored = bp.anchor_image >= 0 && result->images[bp.anchor_image].used;
  const auto gauge_images = std::count(bp.gauge_image.begin(), bp.gauge_image.end(), true);
  result->absolute_position =
      anchored ? "the RPC of " + result->images[bp.anchor_image].name + " (sfm.anchor_image)"
      : gauge_images > 0
          ? fmt::format("the average of {} of the {} images' RPCs: the acquisitions every tile of the city holds",
                        gauge_images, images_used)
          : "the average of " + std::to_string(images_used) + " images' RPCs";
  if (bp.anchor_image >= 0 && !anchored) {
    result->report.warnings.push_back("sfm " + catalog.aoi + ": anchor image " + options.anchor_image +
                                      " was left out; the absolute position is the images' average");
  }
  progress.Info(fmt::format("sfm {}: absolute position from {} (mean BA offset {:.2f} px, largest {:.2f} px)",
                            catalog.aoi, result->absolute_position, mean_offset_px.norm(), largest_offset_px));
  if (images_used == 2) {
    // The most common real input and the minimum: say what it cannot do.
    result->report.warnings.push_back(
        "sfm " + catalog.aoi +
        ": a stereo pair: one intersection per point, so a mismatch cannot be outvoted; ground that either view "
        "cannot see (beside buildings, away from its look direction) gets no height and is filled; no view is left "
        "to hold out for scoring");
  }
  return images_used;
}

}  // namespace

SfmResult RunSfm(const SfmOptions& options, const AoiCatalog& catalog, Progress& progress) {
  options.Check();
  Stopwatch clock;
  SfmResult result;
  result.report.stage = "sfm";
  const Loaded loaded = LoadImages(options, catalog, progress, &result);
  const VerifiedPairs verified = MatchPairs(options, catalog, loaded, progress, &result);
  BundleProblem bp;
  const int used = BuildBundleProblem(options, catalog, loaded, verified, &bp, &result);
  result.before = ComputeStats(ReprojectionErrors(bp));
  if (used < 2 || bp.tracks.empty()) {
    result.report.status = StageStatus::kDegenerate;
    result.report.message = "sfm: " + catalog.aoi + ": " + std::to_string(used) + " usable image(s) and " +
                            std::to_string(bp.tracks.size()) +
                            " tracks; at least 2 images with tie points are needed";
    result.report.seconds = clock.Seconds();
    return result;
  }
  // 5. Bundle adjustment rounds with an outlier cut in between.
  for (int round = 0; round < options.ba_rounds; ++round) {
    RunBundleAdjustment(&bp, options.bundle);
    CutOutliers(&bp, options.max_reprojection_after_ba_px);
  }
  RunBundleAdjustment(&bp, options.bundle);
  const double gauge_shift_m = MoveToGaugeAverage(&bp);
  if (!bp.gauge_image.empty()) result.report.metrics["ba_gauge_shift_m"] = gauge_shift_m;
  result.after = ComputeStats(ReprojectionErrors(bp));
  CollectProducts(bp, loaded, &result);
  if (ReportSfm(options, catalog, bp, progress, &result) < 2) {
    result.report.status = StageStatus::kDegenerate;
    result.report.message = "sfm: " + catalog.aoi + ": fewer than 2 images kept after bundle adjustment";
  }
  result.report.seconds = clock.Seconds();
  return result;
}

}  // namespace skyfall
