// skyfall tile | run-tile | merge
#include <spdlog/spdlog.h>

#include <filesystem>

#include "apps/commands.h"
#include "apps/console.h"
#include "apps/tile_jobs.h"
#include "catalogs/aoi_catalog.h"
#include "tiler/tiling.h"

namespace skyfall::cli {
namespace {

namespace fs = std::filesystem;

void AddTile(CLI::App& app, Runner* runner) {
  auto aois = std::make_shared<std::vector<std::string>>();
  auto out = std::make_shared<std::string>();
  auto opts = std::make_shared<TilingOptions>();
  CLI::App* cmd = app.add_subcommand(
      "tile", "Partition one AOI, or several adjacent AOIs of one city (shared ENU frame), into overlapping tiles");
  cmd->add_option("--aoi", *aois, "aoi.json written by `skyfall ingest` (repeat for adjacent AOIs)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", *out, "Output folder (DIR/tiles)")->required();
  cmd->add_option("--tile-m", opts->tile_m, "Tile core side [m]")->capture_default_str();
  cmd->add_option("--overlap-m", opts->overlap_m, "Overlap margin around each core [m]")->capture_default_str();
  cmd->add_option("--min-coverage", opts->min_coverage, "Fraction of a tile an image must see to be used")
      ->capture_default_str();
  cmd->add_option("--city", opts->city, "City name (default: the AOI name or the AOIs' common prefix)");
  cmd->callback([=] {
    *runner = [=] {
      std::vector<AoiCatalog> catalogs;
      for (const auto& path : *aois) catalogs.push_back(ReadAoiCatalog(path));
      ConsoleProgress progress;
      const TilingResult r = WriteTiles(PlanTiles(*opts, catalogs), *out, progress);
      spdlog::info("tile {}: {}x{} tiles of {} m (+{} m overlap), {} crops, {} tile(s) without images -> {}",
                   r.plan.city, r.plan.grid.cols, r.plan.grid.rows, opts->tile_m, opts->overlap_m,
                   r.report.metrics.at("crops"), r.report.metrics.at("tiles_without_images"), *out);
      return 0;
    };
  });
}

void AddRunTileOptions(CLI::App* cmd, TileRunOptions* o) {
  cmd->add_option("--iterations", o->iterations, "Splat training steps")->capture_default_str();
  cmd->add_option("--resolution", o->downscale, "Training image downscale factor")->capture_default_str();
  cmd->add_option("--depth-prior", o->depth_prior, "'surface', 'none' or 'cmd:COMMAND' (see splat train)")
      ->capture_default_str();
  cmd->add_option("--appearance", o->appearance, "'auto', 'on' or 'off' (see splat train)")->capture_default_str();
  cmd->add_option("--init-max-scale", o->init_max_scale_m, "Cap on the initial Gaussian size [m] (0 = none)")
      ->capture_default_str();
  cmd->add_option("--init-pieces", o->init_pieces, "Up to this many capped Gaussians per SfM point (see splat train)")
      ->capture_default_str();
  cmd->add_option("--init-points", o->init_points,
                  "'auto' or 'dense' (dense heights, the default stage) or 'sparse' (tie points only; no dense stage)")
      ->capture_default_str();
}

void AddRunTile(CLI::App& app, Runner* runner) {
  auto dir = std::make_shared<std::string>();
  auto opts = std::make_shared<TileRunOptions>();
  CLI::App* cmd = app.add_subcommand("run-tile", "Run one tile's pipeline (SfM, splat training); resumable");
  cmd->add_option("dir", *dir, "Tile folder written by `skyfall tile` (DIR/tiles/<id>)")
      ->required()
      ->check(CLI::ExistingDirectory);
  AddRunTileOptions(cmd, opts.get());
  cmd->add_option("--threads", opts->threads, "Threads for this tile (0 = all cores)")->capture_default_str();
  cmd->callback([=] {
    *runner = [=] {
      ConsoleProgress progress;
      const StageReport r = RunTile(*dir, *opts, progress);
      if (r.status == StageStatus::kOk) {
        spdlog::info("run-tile {}: {} {:.1f} s", *dir, r.message.empty() ? "ok" : r.message, r.seconds);
      } else {
        spdlog::warn("run-tile {}: {}: {}", *dir, ToString(r.status), r.message);
      }
      return TileExitCode(r);
    };
  });
}

void AddMerge(CLI::App& app, Runner* runner) {
  auto tiles = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  auto opts = std::make_shared<MergeOptions>();
  CLI::App* cmd = app.add_subcommand(
      "merge", "Stitch the finished tiles (OpenVDB occupancy) into one scene with LOD and a seam report");
  cmd->add_option("--tiles", *tiles, "Tiles folder written by `skyfall tile`")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", *out, "Output folder (DIR/scene)")->required();
  cmd->add_option("--voxel-m", opts->stitch.voxel_m, "Occupancy voxel edge [m]")->capture_default_str();
  cmd->add_option("--lod-levels", opts->lod.max_levels, "Coarser LOD levels to build")->capture_default_str();
  cmd->callback([=] {
    *runner = [=] {
      ConsoleProgress progress;
      const MergeSummary m = MergeTiles(*tiles, *out, *opts, progress);
      const auto& k = m.report.metrics;
      spdlog::info("merge: {} tiles ({} missing), {} Gaussians, {} duplicates removed, {} hole fills, seam ratio {:.2f} "
                   "({:.3f} m across boundaries vs {:.3f} m elsewhere), {:.1f} s -> {}",
                   m.tiles_merged, m.tiles_missing, k.at("gaussians"), k.at("duplicates_removed"), k.at("holes_filled"),
                   m.seam.ratio, m.seam.boundary_mean_step_m, m.seam.interior_mean_step_m, m.report.seconds, *out);
      return 0;
    };
  });
}

}  // namespace

void AddTileCommands(CLI::App& app, Runner* runner) {
  AddTile(app, runner);
  AddRunTile(app, runner);
  AddMerge(app, runner);
}

void AddRunTileOptionsTo(CLI::App* cmd, TileRunOptions* options) { AddRunTileOptions(cmd, options); }

}  // namespace skyfall::cli
