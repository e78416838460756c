#include "apps/jobs.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "sfm/export.h"
#include "splat/dataset.h"
#include "splat/ply.h"

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

}  // namespace

SfmResult RunSfmJob(const SfmOptions& options, const AoiCatalog& catalog, const std::string& out_dir,
                    bool colmap_images, Progress& progress) {
  SfmResult r = RunSfm(options, catalog, progress);
  WriteSfmOutputs(r, catalog, out_dir, colmap_images);
  return r;
}

TrainResult RunTrainJob(TrainJob job, Progress& progress) {
  std::vector<Eigen::Vector3f> points, colours;
  ReadSfmPoints((fs::path(job.sfm_dir) / "points.ply").string(), &points, &colours);
  const std::vector<TrainView> views = LoadTrainViews(job.sfm_dir, job.downscale);
  spdlog::info("splat train: {} views ({} held out), {} SfM points, {} iterations", views.size(),
               std::count_if(views.begin(), views.end(), [](const TrainView& v) { return v.held_out; }),
               points.size(), job.options.iterations);
  std::unique_ptr<DepthPrior> depth_prior;
  if (job.depth_prior == "surface") {
    depth_prior = std::make_unique<SurfaceDepthPrior>(points, 2.0);
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
                                        {"init_pieces", job.init_pieces}});
  const double init_cap_m = job.init_max_scale_m > 0 ? job.init_max_scale_m : std::numeric_limits<double>::infinity();
  const TrainResult r = TrainGaussians(job.options, InitializeFromPoints(points, colours, init_cap_m, job.init_pieces), views,
                                       checkpoints.string(), progress, depth_prior.get());
  WriteGaussiansPly((fs::path(job.out_dir) / "scene.ply").string(), r.cloud);
  WriteFileAtomic((fs::path(job.out_dir) / "train_report.json").string(),
                  TrainReportJson(r, job.options, job.downscale, views.size(), appearance_reason));
  return r;
}

}  // namespace skyfall::cli
