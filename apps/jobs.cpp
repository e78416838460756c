#include "apps/jobs.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <cstdio>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>

#include "catalogs/tile_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "sfm/export.h"
#include "splat/dataset.h"
#include "splat/ply.h"
#include "tiler/raster.h"

namespace skyfall::cli {
namespace {

namespace fs = std::filesystem;

std::string TrainReportJson(const TrainResult& r, const TrainOptions& o, int downscale, std::size_t views,
                            const std::string& appearance_reason) {
  nlohmann::json series = nlohmann::json::array();
  for (const TrainSample& s : r.series) {
    series.push_back({{"iteration", s.iteration},
                      {"elapsed_s", s.seconds},
                      {"loss", std::isfinite(s.loss) ? nlohmann::json(s.loss) : nlohmann::json()},
                      {"psnr_test_db", std::isfinite(s.psnr_test_db) ? nlohmann::json(s.psnr_test_db) : nlohmann::json()},
                      {"gaussians", s.gaussians}});
  }
  const nlohmann::json doc = {
      {"status", ToString(r.report.status)},
      {"iterations", o.iterations},
      {"resumed_from_iteration", r.start_iteration},
      {"resolution_downscale", downscale},
      {"views", views},
      {"lambda_dssim", o.lambda_dssim},
      {"lambda_opacity", o.lambda_opacity},
      {"gaussians", r.cloud.size()},
      {"seconds_this_run", r.report.seconds},
      {"enabled", {{"entropy_opacity", o.lambda_opacity > 0},
                   {"densification", o.densify_from <= o.densify_until},
                   {"appearance_model", o.appearance.enabled},
                   {"pseudo_camera_depth", o.pseudo_interval > 0}}},
      {"appearance", {{"reason", appearance_reason},
                      {"fused_image", r.appearance_image.empty() ? nlohmann::json() : nlohmann::json(r.appearance_image)}}},
      {"series", series}};
  return doc.dump(2) + "\n";
}

// Decides whether the appearance model runs, and says why.
std::string ResolveAppearance(const std::string& mode, const std::vector<TrainView>& views, TrainOptions* o) {
  const int dates = DistinctAcquisitionDates(views);
  if (mode == "on" || mode == "off") {
    o->appearance.enabled = mode == "on";
    return "--appearance " + mode;
  }
  if (mode != "auto") throw Error("splat", "--appearance", "'" + mode + "' is not 'auto', 'on' or 'off'");
  o->appearance.enabled = dates >= 2;
  return "auto: training views from " + std::to_string(dates) + " acquisition date" + (dates == 1 ? "" : "s");
}

// A checkpoint is resumed only by a run with the same settings; otherwise it
// is set aside (renamed, not deleted) and training starts again.
void SetAsideStaleCheckpoint(const fs::path& dir, const nlohmann::json& settings) {
  const fs::path settings_path = dir / "settings.json";
  const fs::path checkpoint = dir / "checkpoint.bin";
  if (fs::exists(checkpoint)) {
    nlohmann::json previous;
    try {
      previous = nlohmann::json::parse(ReadTextFile(settings_path.string()));
    } catch (const std::exception&) {
    }
    if (previous != settings) {
      spdlog::warn("splat train: {} was written with other settings; moved to checkpoint.bin.stale, starting again",
                   checkpoint.string());
      fs::rename(checkpoint, dir / "checkpoint.bin.stale");
    }
  }
  fs::create_directories(dir);
  WriteFileIfChanged(settings_path.string(), settings.dump(2) + "\n");
}

std::string DensePly(const HeightGrid& g) {
  std::size_t count = 0;
  for (float h : g.height_m) count += std::isfinite(h) ? 1 : 0;
  std::string out = "ply\nformat ascii 1.0\ncomment skyfall dense heights, ENU metres, one point per " +
                    std::to_string(g.cell_m) + " m cell\nelement vertex " + std::to_string(count) +
                    "\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\n"
                    "property uchar green\nproperty uchar blue\nproperty float matching_cost\nproperty uchar filled\nend_header\n";
  char line[160];
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = g.Index(i, j);
      if (!std::isfinite(g.height_m[k])) continue;
      std::snprintf(line, sizeof line, "%.3f %.3f %.3f %d %d %d %.4f %d\n", g.x0_m + i * g.cell_m,
                    g.y0_m + j * g.cell_m, g.height_m[k], g.rgb[k][0], g.rgb[k][1], g.rgb[k][2], g.cost[k],
                    g.filled[k]);
      out += line;
    }
  return out;
}

}  // namespace

namespace {

nlohmann::json ExtentJson(const std::optional<GroundBox>& extent) {
  return extent ? BoxToJson(*extent) : nlohmann::json();
}

// Every setting that changes the heights: a finished stage is reused only
// when they all match.
nlohmann::json DenseOptionsJson(const DenseOptions& o) {
  return {{"cell_m", o.cell_m},
          {"height_step_m", o.height_step_m},
          {"height_margin_m", o.height_margin_m},
          {"height_percentile", o.height_percentile},
          {"window_cells", o.window_cells},
          {"max_pairs", o.max_pairs},
          {"min_pair_matches", o.min_pair_matches},
          {"min_pair_angle_deg", o.min_pair_angle_deg},
          {"max_pair_angle_deg", o.max_pair_angle_deg},
          {"cost_truncation", o.cost_truncation},
          {"min_std", o.min_std},
          {"sgm_p1", o.sgm_p1},
          {"sgm_p2", o.sgm_p2},
          {"max_cost", o.max_cost},
          {"max_median_deviation_m", o.max_median_deviation_m},
          {"fill_holes", o.fill_holes},
          {"fill_radius_m", o.fill_radius_m},
          {"max_fill_reach_m", o.max_fill_reach_m},
          {"visibility_pass", o.visibility_pass},
          {"visibility_tolerance_m", o.visibility_tolerance_m},
          {"visibility_prior_pairs", o.visibility_prior_pairs}};
}

}  // namespace

bool DenseDone(const std::string& sfm_dir, const DenseOptions& options, const std::optional<GroundBox>& extent_enu_m) {
  const fs::path dir(sfm_dir);
  try {
    const nlohmann::json doc = nlohmann::json::parse(ReadTextFile((dir / "dense_report.json").string()));
    return doc.value("status", "") == "ok" && fs::exists(dir / "dense.ply") &&
           doc.value("extent_enu_m", nlohmann::json()) == ExtentJson(extent_enu_m) &&
           doc.value("options", nlohmann::json()) == DenseOptionsJson(options);
  } catch (const std::exception&) {
    return false;
  }
}

DenseResult RunDenseJob(const DenseOptions& options, const std::string& sfm_dir, Progress& progress,
                        const std::optional<GroundBox>& extent_enu_m) {
  const fs::path dir(sfm_dir);
  const std::string report_path = (dir / "sfm_report.json").string();
  std::vector<DenseView> views;
  std::map<std::string, int> index;
  for (CameraEntry& entry : ReadCameraEntries((dir / "cameras.json").string())) {
    FloatImage pixels = ReadFloatImage(entry.source_image);
    if (pixels.width_px != entry.camera.width_px || pixels.height_px != entry.camera.height_px)
      throw Error("dense", entry.source_image, "size differs from cameras.json");
    index[entry.name] = static_cast<int>(views.size());
    DenseView v;
    v.name = std::move(entry.name);
    v.camera = entry.camera;
    v.width_px = pixels.width_px;
    v.height_px = pixels.height_px;
    v.bands = pixels.bands;
    v.pixels = std::move(pixels.values);
    views.push_back(std::move(v));
  }
  nlohmann::json sfm_report;
  try {
    sfm_report = nlohmann::json::parse(ReadTextFile(report_path));
  } catch (const nlohmann::json::exception& e) {
    throw Error("dense", report_path, std::string("not valid JSON: ") + e.what());
  }
  std::vector<DensePair> pairs;
  for (const nlohmann::json& p : sfm_report.value("pairs", nlohmann::json::array())) {
    const auto a = index.find(p.value("a", std::string())), b = index.find(p.value("b", std::string()));
    if (a != index.end() && b != index.end()) pairs.push_back({a->second, b->second, p.value("verified", 0)});
  }
  std::vector<Eigen::Vector3f> points_f, colours;
  ReadSfmPoints((dir / "points.ply").string(), &points_f, &colours);
  std::vector<Eigen::Vector3d> points;
  for (const auto& p : points_f) points.push_back(p.cast<double>());

  DenseResult r = RunDenseHeights(options, views, pairs, points, progress, extent_enu_m);
  if (r.report.status == StageStatus::kOk) WriteFileAtomic((dir / "dense.ply").string(), DensePly(r.grid));
  else fs::remove(dir / "dense.ply");  // an earlier run's heights must not outlive a failed rerun
  nlohmann::json used = nlohmann::json::array();
  for (const DensePair& p : r.pairs_used) used.push_back({{"a", views[p.a].name}, {"b", views[p.b].name}, {"verified", p.verified}});
  const nlohmann::json doc = {{"status", ToString(r.report.status)}, {"message", r.report.message},
                              {"seconds", r.report.seconds},      {"metrics", r.report.metrics},
                              {"cell_m", r.grid.cell_m},          {"extent_enu_m", ExtentJson(extent_enu_m)},
                              {"options", DenseOptionsJson(options)}, {"pairs", used}};
  WriteFileAtomic((dir / "dense_report.json").string(), doc.dump(2) + "\n");
  return r;
}

SfmResult RunSfmJob(const SfmOptions& options, const AoiCatalog& catalog, const std::string& out_dir,
                    bool colmap_images, Progress& progress) {
  SfmResult r = RunSfm(options, catalog, progress);
  WriteSfmOutputs(r, catalog, out_dir, colmap_images);
  return r;
}

TrainResult RunTrainJob(TrainJob job, Progress& progress) {
  std::vector<Eigen::Vector3f> points, colours;
  ReadSfmPoints((fs::path(job.sfm_dir) / "points.ply").string(), &points, &colours);
  const fs::path dense_path = fs::path(job.sfm_dir) / "dense.ply";
  if (job.init_points != "auto" && job.init_points != "dense" && job.init_points != "sparse")
    throw Error("splat", "--init-points", "'" + job.init_points + "' is not 'auto', 'dense' or 'sparse'");
  if (job.init_points == "dense" && !fs::exists(dense_path))
    throw Error("splat", dense_path.string(), "missing: run `skyfall dense --sfm " + job.sfm_dir +
                                                  "` first, or train with --init-points sparse");
  const bool dense = job.init_points == "dense" || (job.init_points == "auto" && fs::exists(dense_path));
  const std::size_t tie_points = points.size();
  if (dense) {
    std::vector<Eigen::Vector3f> dense_points, dense_colours;
    ReadSfmPoints(dense_path.string(), &dense_points, &dense_colours);
    ThinToGrid(job.init_spacing_m, dense_points, dense_colours, points, colours, &points, &colours);
  }
  if (job.densify != "auto" && job.densify != "on" && job.densify != "off")
    throw Error("splat", "--densify", "'" + job.densify + "' is not 'auto', 'on' or 'off'");
  const bool densify = job.densify == "on" || (job.densify == "auto" && !dense);
  if (!densify) job.options.densify_from = job.options.iterations + 1;  // never reached
  const std::vector<TrainView> views = LoadTrainViews(job.sfm_dir, job.downscale);
  spdlog::info("splat train: {} views ({} held out), {} initial points ({}), {} iterations, densification {}",
               views.size(),
               std::count_if(views.begin(), views.end(), [](const TrainView& v) { return v.held_out; }),
               points.size(),
               dense ? fmt::format("dense heights thinned to {} m, and tie points in their holes", job.init_spacing_m)
                     : fmt::format("{} tie points", tie_points),
               job.options.iterations, densify ? "on" : "off");
  std::unique_ptr<DepthPrior> depth_prior;
  if (job.depth_prior == "surface") {
    depth_prior = std::make_unique<SurfaceDepthPrior>(points, dense ? 2.0 * job.init_spacing_m : 2.0);
  } else if (job.depth_prior.rfind("cmd:", 0) == 0) {
    fs::create_directories(fs::path(job.out_dir) / "pseudo");
    depth_prior = std::make_unique<CommandDepthPrior>(job.depth_prior.substr(4), (fs::path(job.out_dir) / "pseudo").string());
  } else if (job.depth_prior != "none") {
    throw Error("splat", "--depth-prior", "'" + job.depth_prior + "' is not 'surface', 'none' or 'cmd:...'");
  }
  if (!depth_prior) job.options.pseudo_interval = 0;
  const std::string appearance_reason = ResolveAppearance(job.appearance, views, &job.options);
  spdlog::info("splat train: appearance model {} ({})", job.options.appearance.enabled ? "on" : "off",
               appearance_reason);
  const fs::path checkpoints = fs::path(job.out_dir) / "checkpoints";
  SetAsideStaleCheckpoint(checkpoints, {{"appearance_model", job.options.appearance.enabled},
                                        {"resolution_downscale", job.downscale},
                                        {"depth_prior", job.depth_prior},
                                        {"seed", job.options.seed},
                                        {"init_max_scale_m", job.init_max_scale_m},
                                        {"init_pieces", job.init_pieces},
                                        {"init_points", dense ? "dense" : "sparse"},
                                        {"init_spacing_m", job.init_spacing_m},
                                        {"densify", densify}});
  const double init_cap_m = job.init_max_scale_m > 0 ? job.init_max_scale_m : std::numeric_limits<double>::infinity();
  const TrainResult r = TrainGaussians(job.options, InitializeFromPoints(points, colours, init_cap_m, dense ? 1 : job.init_pieces), views,
                                       checkpoints.string(), progress, depth_prior.get());
  WriteGaussiansPly((fs::path(job.out_dir) / "scene.ply").string(), r.cloud);
  WriteFileAtomic((fs::path(job.out_dir) / "train_report.json").string(),
                  TrainReportJson(r, job.options, job.downscale, views.size(), appearance_reason));
  return r;
}

}  // namespace skyfall::cli
