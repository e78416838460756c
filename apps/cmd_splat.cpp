// skyfall splat train | render
#include <spdlog/spdlog.h>

#include <cmath>

#include "apps/commands.h"
#include "apps/console.h"
#include "pipeline/stage_jobs.h"
#include "products/view_eval.h"
#include "splat/trainer.h"

namespace skyfall::cli {
namespace {


void AddTrain(CLI::App& splat, Runner* runner) {
  auto sfm = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  auto stage = std::make_shared<TrainStageOptions>();
  TrainOptions& o = stage->optimizer;
  CLI::App* cmd = splat.add_subcommand("train", "Train 3D Gaussians on an SfM folder (reconstruction stage)");
  cmd->add_option("--sfm", *sfm, "Folder written by `skyfall sfm`")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", *out, "Output folder: scene.ply, train_report.json, checkpoints/")->required();
  cmd->add_option("--iterations", o.iterations, "Optimization steps")->capture_default_str();
  cmd->add_option("--resolution", stage->downscale, "Image downscale factor (1 = full resolution; 0 = automatic: 2 for imagery finer than 1 m GSD, 1 for coarser)")
      ->capture_default_str();
  cmd->add_option("--lambda-opacity", o.lambda_opacity, "Entropy opacity weight (0 = off)")->capture_default_str();
  cmd->add_option("--seed", o.seed, "Random seed")->capture_default_str();
  cmd->add_option("--checkpoint-every", o.checkpoint_interval, "Checkpoint interval [iterations]")->capture_default_str();
  cmd->add_option("--depth-prior", stage->depth_prior,
                  "Pseudo-camera depth prior: 'surface' (built in: the initial points' height field), 'none', or "
                  "'cmd:COMMAND' with {in} (view PNG) and {out} (depth TIFF to write)")
      ->capture_default_str();
  cmd->add_option("--pseudo-every", o.pseudo_interval, "Iterations between pseudo views (0 = off)")->capture_default_str();
  cmd->add_option("--lambda-depth", o.lambda_depth, "Depth loss weight")->capture_default_str();
  AddModeOption(cmd, "--appearance", &stage->appearance,
                "Per-image appearance model: 'auto' (on for multi-date views), 'on' or 'off'");
  cmd->add_option("--appearance-image", o.appearance_image,
                  "Training view whose appearance is fused into scene.ply (default: the most typical one)");
  cmd->add_option("--densify-from", o.density.from_step, "First densification step")->capture_default_str();
  cmd->add_option("--densify-until", o.density.until_step, "Last step that adds Gaussians")->capture_default_str();
  cmd->add_option("--opacity-reg-from", o.opacity_reg_from, "First step of the entropy opacity term")
      ->capture_default_str();
  cmd->add_option("--init-max-scale", stage->init_max_scale_m, "Cap on the initial Gaussian size [m] (0 = none)")
      ->capture_default_str();
  cmd->add_option("--init-pieces", stage->init_pieces,
                  "Up to this many capped Gaussians per SfM point, covering the space to its neighbours")
      ->capture_default_str();
  AddModeOption(cmd, "--init-points", &stage->init_points,
                "Initial Gaussians from 'dense' (SFM/dense.ply of `skyfall dense`), 'sparse' (the tie points) or "
                "'auto' (dense when dense.ply exists)");
  AddModeOption(cmd, "--densify", &stage->densify,
                "Clone, split and prune during training: 'on', 'off', or 'auto' (off when starting from dense "
                "heights)");
  cmd->add_flag("--snapshots", o.keep_snapshots,
                "Keep checkpoints/snapshots/scene_<iteration>.ply (for `skyfall report`: DSM error vs time)");
  cmd->callback([=] {
    *runner = [=] {
      ConsoleProgress progress;
      const TrainJobResult r = RunTrainJob(*stage, *sfm, *out, progress);
      const double psnr = r.train.series.empty() ? NAN : r.train.series.back().psnr_test_db;
      spdlog::info("splat train: {} Gaussians, held-out PSNR {:.2f} dB, {:.1f} s -> {}", r.train.cloud.size(), psnr,
                   r.train.report.seconds, *out);
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
      ConsoleProgress progress;
      RenderSceneJob(*scene, *cameras, *out, *downscale, progress);
      return 0;
    };
  });
}

void AddOrbit(CLI::App& splat, Runner* runner) {
  auto tile = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  auto o = std::make_shared<EvalOrbitOptions>();
  CLI::App* cmd = splat.add_subcommand(
      "orbit", "Write orbit cameras around a tile (between the synthesis stage's look-at points) as a cameras.json");
  cmd->add_option("--tile", *tile, "Tile folder (tile.json and dense/dense.ply)")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", *out, "cameras.json to write")->required();
  cmd->add_option("--elevations", o->elevations_deg, "Elevations [deg]")->delimiter(',')->capture_default_str();
  cmd->add_option("--views", o->views_per_elevation, "Views per look-at point and elevation")->capture_default_str();
  cmd->add_option("--size", o->width_px, "Image side [px]")->capture_default_str();
  cmd->add_option("--fov", o->fov_deg, "Field of view [deg]")->capture_default_str();
  cmd->callback([=] {
    *runner = [=] {
      o->height_px = o->width_px;
      const int n = WriteEvalOrbitCameras(*tile, *o, *out);
      spdlog::info("splat orbit: {} cameras -> {}", n, *out);
      return 0;
    };
  });
}

void AddCompare(CLI::App& splat, Runner* runner) {
  auto cameras = std::make_shared<std::string>(), truth = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  auto renders = std::make_shared<std::vector<std::string>>();
  CLI::App* cmd = splat.add_subcommand("compare", "Masked PSNR and SSIM of renders against truth images, with a gallery");
  cmd->add_option("--cameras", *cameras, "cameras.json of the views")->required()->check(CLI::ExistingFile);
  cmd->add_option("--truth", *truth, "Folder of <name>.png and <name>_mask.png (`synth --render-cameras`)")
      ->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--render", *renders, "Folder of <name>_rgb.png (`splat render`); repeatable")
      ->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", *out, "Folder for compare.json and gallery.png")->required();
  cmd->callback([=] {
    *runner = [=] {
      ConsoleProgress progress;
      const ViewComparison c = CompareViews(*cameras, *truth, *renders, *out, progress);
      for (const auto& [el, psnr] : c.psnr_db) {
        std::string line;
        for (std::size_t d = 0; d < psnr.size(); ++d)
          line += fmt::format("  {}: PSNR {:.2f} dB, SSIM {:.3f}", (*renders)[d], psnr[d], c.ssim.at(el)[d]);
        spdlog::info("splat compare: elevation {:.0f} deg{}", el, line);
      }
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
  AddOrbit(*splat, runner);
  AddCompare(*splat, runner);
}

}  // namespace skyfall::cli
