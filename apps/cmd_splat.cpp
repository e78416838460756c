// skyfall splat train | render
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "apps/console.h"
#include "apps/jobs.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "splat/dataset.h"
#include "splat/ply.h"
#include "splat/trainer.h"
#include "tiler/raster.h"

namespace skyfall::cli {
namespace {

namespace fs = std::filesystem;

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
  auto appearance = std::make_shared<std::string>("auto");
  cmd->add_option("--appearance", *appearance,
                  "Per-image appearance model: 'auto' (on for multi-date views), 'on' or 'off'")
      ->capture_default_str();
  cmd->add_option("--appearance-image", opts->appearance_image,
                  "Training view whose appearance is fused into scene.ply (default: the most typical one)");
  cmd->add_option("--densify-from", opts->densify_from, "First densification step")->capture_default_str();
  cmd->add_option("--densify-until", opts->densify_until, "Last step that adds Gaussians")->capture_default_str();
  cmd->add_option("--opacity-reg-from", opts->opacity_reg_from, "First step of the entropy opacity term")
      ->capture_default_str();
  auto init_max_scale = std::make_shared<double>(TrainJob{}.init_max_scale_m);
  cmd->add_option("--init-max-scale", *init_max_scale, "Cap on the initial Gaussian size [m] (0 = none)")
      ->capture_default_str();
  auto init_pieces = std::make_shared<int>(TrainJob{}.init_pieces);
  cmd->add_option("--init-pieces", *init_pieces,
                  "Up to this many capped Gaussians per SfM point, covering the space to its neighbours")
      ->capture_default_str();
  auto init_points = std::make_shared<std::string>(TrainJob{}.init_points);
  cmd->add_option("--init-points", *init_points,
                  "Initial Gaussians from 'dense' (SFM/dense.ply of `skyfall dense`), 'sparse' (the tie points) or "
                  "'auto' (dense when dense.ply exists)")
      ->capture_default_str();
  auto densify = std::make_shared<std::string>(TrainJob{}.densify);
  cmd->add_option("--densify", *densify,
                  "Clone, split and prune during training: 'on', 'off', or 'auto' (off when starting from dense "
                  "heights)")
      ->capture_default_str();
  cmd->add_flag("--snapshots", opts->keep_snapshots,
                "Keep checkpoints/snapshots/scene_<iteration>.ply (for `skyfall report`: DSM error vs time)");
  cmd->callback([=] {
    *runner = [=] {
      ConsoleProgress progress;
      TrainJob job;
      job.sfm_dir = *sfm;
      job.out_dir = *out;
      job.options = *opts;
      job.downscale = *downscale;
      job.depth_prior = *prior;
      job.appearance = *appearance;
      job.init_max_scale_m = *init_max_scale;
      job.init_pieces = *init_pieces;
      job.init_points = *init_points;
      job.densify = *densify;
      const TrainResult r = RunTrainJob(job, progress);
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
