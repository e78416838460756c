// skyfall sfm --aoi DIR/<AOI>/aoi.json --out DIR/<AOI>/sfm
#include <spdlog/spdlog.h>

#include "apps/commands.h"
#include "apps/console.h"
#include "pipeline/stage_jobs.h"
#include "catalogs/aoi_catalog.h"
#include "catalogs/tile_catalog.h"
#include "sfm/sfm.h"

namespace skyfall::cli {

void AddSfmCommand(CLI::App& app, Runner* runner) {
  auto aoi = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto opts = std::make_shared<SfmOptions>();
  auto no_images = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "sfm", "RPC -> pinhole cameras, SIFT tie points, bundle adjustment; writes cameras.json, points.ply, "
             "sfm_report.json and a COLMAP text model");
  cmd->add_option("--aoi", *aoi, "AOI catalog written by `skyfall ingest`")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", *out, "Output folder")->required();
  cmd->add_option("--max-features", opts->features.max_features, "SIFT keypoints per image")->capture_default_str();
  cmd->add_flag("--no-colmap-images", *no_images, "Write the COLMAP model without the de-skewed images");
  cmd->callback([runner, aoi, out, opts, no_images] {
    *runner = [aoi, out, opts, no_images] {
      const AoiCatalog catalog = ReadAoiCatalog(*aoi);
      ConsoleProgress progress;
      const SfmResult r = RunSfmJob(*opts, catalog, *out, !*no_images, progress);
      const auto& m = r.report.metrics;
      for (const auto& w : r.report.warnings) spdlog::warn("{}", w);
      if (r.report.status != StageStatus::kOk) {
        spdlog::warn("{}", r.report.message);
        return kExitDegenerate;
      }
      spdlog::info("sfm {}: {} images, {} points; pinhole max {:.4f} px; reprojection median {:.3f} -> {:.3f} px; "
                   "{:.1f} s -> {}",
                   catalog.aoi, m.at("num_images_used"), m.at("num_points"), m.at("dlt_max_error_px"),
                   r.before.median_px, r.after.median_px, r.report.seconds, *out);
      return 0;
    };
  });
}

void AddDenseCommand(CLI::App& app, Runner* runner) {
  auto sfm = std::make_shared<std::string>();
  auto opts = std::make_shared<DenseOptions>();
  auto tile = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "dense", "Dense heights from an SfM folder (ground-space plane sweep, NCC, semi-global matching); writes "
               "dense.ply and dense_report.json beside cameras.json");
  cmd->add_option("--sfm", *sfm, "Folder written by `skyfall sfm`")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--tile", *tile, "tile.json whose extent clips the grid (run-tile passes its own)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--cell", opts->cell_m, "Grid cell [m]; 0: follows the imagery (0.5 m below 0.75 m GSD)")->capture_default_str();
  cmd->add_option("--height-step", opts->height_step_m, "Sweep step [m]")->capture_default_str();
  cmd->add_option("--window", opts->window_cells, "NCC window side [cells], odd")->capture_default_str();
  cmd->add_option("--max-pairs", opts->pairs.max, "Image pairs used, most tie points first")->capture_default_str();
  cmd->add_option("--p1", opts->sgm.p1, "SGM penalty for a one-step height change")->capture_default_str();
  cmd->add_option("--p2", opts->sgm.p2, "SGM penalty for a larger height change")->capture_default_str();
  cmd->add_option("--max-cost", opts->max_cost, "Cells matching worse than this get no height")->capture_default_str();
  cmd->add_flag("--visibility-pass,!--no-visibility-pass", opts->visibility.pass,
                "Second sweep scoring each height only with the pairs that see it")
      ->capture_default_str();
  cmd->add_option("--visibility-tolerance", opts->visibility.tolerance_m,
                  "First-surface error allowed before a point counts as hidden [m]")
      ->capture_default_str();
  cmd->add_option("--visibility-prior", opts->visibility.prior_pairs,
                  "Pairs of truncation cost added to each height's mean in the second sweep")
      ->capture_default_str();
  cmd->add_option("--fill-radius", opts->fill.radius_m,
                  "Holes that views see take the terrain plus the lowest height above it within this distance [m]")
      ->capture_default_str();
  cmd->callback([runner, sfm, opts, tile] {
    *runner = [sfm, opts, tile] {
      ConsoleProgress progress;
      std::optional<GroundBox> extent;
      if (!tile->empty()) extent = ReadTileSpec(*tile).extent;
      const DenseResult r = RunDenseJob(*opts, *sfm, progress, extent);
      if (r.report.status != StageStatus::kOk) {
        spdlog::warn("dense: {}", r.report.message);
        return kExitDegenerate;
      }
      const auto& m = r.report.metrics;
      spdlog::info("dense: {}x{} cells x {} heights, {} pairs, {:.1f}% with a height; {:.1f} s -> {}/dense.ply", r.grid.nx,
                   r.grid.ny, m.at("heights"), m.at("pairs"), 100.0 * m.at("valid_fraction"), r.report.seconds, *sfm);
      return 0;
    };
  });
}

}  // namespace skyfall::cli
