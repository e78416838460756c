// skyfall splat train | render
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "apps/console.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "splat/dataset.h"
#include "splat/ply.h"
#include "splat/trainer.h"
#include "tiler/raster.h"

namespace skyfall::cli {
namespace {

namespace fs = std::filesystem;

std::string TrainReportJson(const TrainResult& r, const TrainOptions& o, int downscale, std::size_t views) {
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
                   {"appearance_model", false},
                   {"pseudo_camera_depth", o.pseudo_interval > 0}}},
      {"series", series}};
  return doc.dump(2) + "\n";
}

void AddTrain(CLI::App& splat, Runner* runner) {
  auto sfm = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  auto opts = std::make_shared<TrainOptions>();
  auto downscale = std::make_shared<int>(1);
  CLI::App* cmd = splat.add_subcommand("train", "Train 3D Gaussians on an SfM folder (reconstruction stage)");
  cmd->add_option("--sfm", *sfm, "Folder written by `skyfall sfm`")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", *out, "Output folder: scene.ply, train_report.json, checkpoints/")->required();
  cmd->add_option("--iterations", opts->iterations, "Optimization steps")->capture_default_str();
  cmd->add_option("--resolution", *downscale, "Image downscale factor (1 = full resolution)")->capture_default_str();
  cmd->add_option("--lambda-opacity", opts->lambda_opacity, "Entropy opacity weight (0 = off)")->capture_default_str();
  cmd->add_option("--seed", opts->seed, "Random seed")->capture_default_str();
  cmd->add_option("--checkpoint-every", opts->checkpoint_interval, "Checkpoint interval [iterations]")->capture_default_str();
  auto prior = std::make_shared<std::string>("surface");
  cmd->add_option("--depth-prior", *prior,
                  "Pseudo-camera depth prior: 'surface' (built in: the SfM points' height field), 'none', or "
                  "'cmd:COMMAND' with {in} (view PNG) and {out} (depth TIFF to write)")
      ->capture_default_str();
  opts->pseudo_interval = 4;
  cmd->add_option("--pseudo-every", opts->pseudo_interval, "Iterations between pseudo views (0 = off)")->capture_default_str();
  cmd->add_option("--lambda-depth", opts->lambda_depth, "Depth loss weight")->capture_default_str();
  cmd->add_flag("--snapshots", opts->keep_snapshots,
                "Keep checkpoints/snapshots/scene_<iteration>.ply (for `skyfall report`: DSM error vs time)");
  cmd->callback([=] {
    *runner = [=] {
      std::vector<Eigen::Vector3f> points, colours;
      ReadSfmPoints((fs::path(*sfm) / "points.ply").string(), &points, &colours);
      const std::vector<TrainView> views = LoadTrainViews(*sfm, *downscale);
      spdlog::info("splat train: {} views ({} held out), {} SfM points, {} iterations", views.size(),
                   std::count_if(views.begin(), views.end(), [](const TrainView& v) { return v.held_out; }),
                   points.size(), opts->iterations);
      std::unique_ptr<DepthPrior> depth_prior;
      if (*prior == "surface") {
        depth_prior = std::make_unique<SurfaceDepthPrior>(points, 2.0);
      } else if (prior->rfind("cmd:", 0) == 0) {
        fs::create_directories(fs::path(*out) / "pseudo");
        depth_prior = std::make_unique<CommandDepthPrior>(prior->substr(4), (fs::path(*out) / "pseudo").string());
      } else if (*prior != "none") {
        throw Error("splat", "--depth-prior", "'" + *prior + "' is not 'surface', 'none' or 'cmd:...'");
      }
      if (!depth_prior) opts->pseudo_interval = 0;
      ConsoleProgress progress;
      const TrainResult r = TrainGaussians(*opts, InitializeFromPoints(points, colours), views,
                                           (fs::path(*out) / "checkpoints").string(), progress, depth_prior.get());
      WriteGaussiansPly((fs::path(*out) / "scene.ply").string(), r.cloud);
      WriteFileAtomic((fs::path(*out) / "train_report.json").string(), TrainReportJson(r, *opts, *downscale, views.size()));
      const double psnr = r.series.empty() ? NAN : r.series.back().psnr_test_db;
      spdlog::info("splat train: {} Gaussians, held-out PSNR {:.2f} dB, {:.1f} s -> {}", r.cloud.size(), psnr,
                   r.report.seconds, *out);
      return 0;
    };
  });
}

void AddRender(CLI::App& splat, Runner* runner) {
  auto scene = std::make_shared<std::string>(), cameras = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  auto downscale = std::make_shared<int>(1);
  CLI::App* cmd = splat.add_subcommand("render", "Render a Gaussian scene from the cameras of a cameras.json");
  cmd->add_option("--scene", *scene, "Inria 3DGS PLY")->required()->check(CLI::ExistingFile);
  cmd->add_option("--cameras", *cameras, "cameras.json written by `skyfall sfm`")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", *out, "Output folder for <name>_rgb.png, <name>_depth.png and <name>_depth.tif")->required();
  cmd->add_option("--resolution", *downscale, "Downscale factor")->capture_default_str();
  cmd->callback([=] {
    *runner = [=] {
      const GaussianCloud cloud = ReadGaussiansPly(*scene);
      const auto cams = ReadCameras(*cameras);
      ConsoleProgress progress;
      progress.Begin("splat render", cams.size());
      std::size_t done = 0;
      for (const auto& [name, full] : cams) {
        const PinholeCamera cam = DownscaledCamera(full, *downscale);
        const RenderOutput<float> r = RenderGaussians(cloud, cam, RasterOptions{});
        const int w = r.width_px, h = r.height_px;
        std::vector<std::uint8_t> rgb(3 * static_cast<size_t>(w) * h), grey(static_cast<size_t>(w) * h);
        for (size_t k = 0; k < rgb.size(); ++k) rgb[k] = static_cast<std::uint8_t>(std::clamp(r.rgb[k], 0.0f, 1.0f) * 255.0f + 0.5f);
        // Depth: absolute camera depth as float, and a min-max visualization.
        std::vector<float> depth(r.depth.size());
        float lo = 1e30f, hi = -1e30f;
        for (size_t k = 0; k < depth.size(); ++k) {
          if (r.alpha[k] < 0.5f) continue;
          lo = std::min(lo, r.depth[k]);
          hi = std::max(hi, r.depth[k]);
        }
        for (size_t k = 0; k < depth.size(); ++k) {
          depth[k] = r.alpha[k] >= 0.5f ? static_cast<float>(r.depth[k] + r.reference_depth_m) : NAN;
          grey[k] = r.alpha[k] >= 0.5f && hi > lo ? static_cast<std::uint8_t>(255.0f * (hi - r.depth[k]) / (hi - lo)) : 0;
        }
        WriteBytePng((fs::path(*out) / (name + "_rgb.png")).string(), w, h, 3, rgb.data());
        WriteBytePng((fs::path(*out) / (name + "_depth.png")).string(), w, h, 1, grey.data());
        WriteFloatTiff((fs::path(*out) / (name + "_depth.tif")).string(), w, h, depth.data());
        progress.Advance(++done, name);
      }
      progress.End();
      return 0;
    };
  });
}

}  // namespace

void AddSplatCommand(CLI::App& app, Runner* runner) {
  CLI::App* splat = app.add_subcommand("splat", "3D Gaussian Splatting: train and render");
  splat->require_subcommand(1);
  AddTrain(*splat, runner);
  AddRender(*splat, runner);
}

}  // namespace skyfall::cli
