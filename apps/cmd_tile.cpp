// skyfall tile | run-tile | merge
#include <spdlog/spdlog.h>

#include <filesystem>

#include "apps/commands.h"
#include "apps/console.h"
#include "apps/run_flags.h"
#include "pipeline/exit_codes.h"
#include "pipeline/merge_tiles.h"
#include "pipeline/tile_run.h"
#include "catalogs/aoi_catalog.h"
#include "tiling/tiling.h"

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
  cmd->add_option("--tile-m", opts->tile_m, "Tile core side [m]; 0: sized by the imagery (about --tile-cells cells)")->capture_default_str();
  cmd->add_option("--tile-cells", opts->tile_cells, "What an automatic tile holds a side [dense cells]")->capture_default_str();
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
                   r.plan.city, r.plan.grid.cols, r.plan.grid.rows, r.plan.grid.tile_m, opts->overlap_m,
                   r.report.metrics.at("crops"), r.report.metrics.at("tiles_without_images"), *out);
      return 0;
    };
  });
}

void AddRunTile(CLI::App& app, Runner* runner) {
  auto dir = std::make_shared<std::string>();
  auto threads = std::make_shared<int>(0);
  CLI::App* cmd = app.add_subcommand("run-tile", "Run one tile's pipeline (SfM, dense heights, splat training); resumable");
  cmd->add_option("dir", *dir, "Tile folder written by `skyfall tile` (DIR/tiles/<id>)")
      ->required()
      ->check(CLI::ExistingDirectory);
  auto flags = std::make_shared<RunFlags>(cmd);
  flags->AddTileFlags();
  cmd->add_option("--threads", *threads, "Threads for this tile (0 = all cores)")->capture_default_str();
  cmd->callback([=] {
    *runner = [=] {
      const RunOptions options = flags->Resolve();
      options.Check();
      ConsoleProgress progress;
      const StageReport r = RunTile(*dir, options, *threads, progress);
      if (r.status == StageStatus::kOk) {
        spdlog::info("run-tile {}: {} {:.1f} s", *dir, r.message.empty() ? "ok" : r.message, r.seconds);
      } else {
        spdlog::warn("run-tile {}: {}: {}", *dir, ToString(r.status), r.message);
      }
      return ExitCodeOf(r.status);
    };
  });
}

void AddMerge(CLI::App& app, Runner* runner) {
  auto tiles = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "merge", "Stitch the finished tiles (OpenVDB occupancy) into one scene with LOD and a seam report");
  cmd->add_option("--tiles", *tiles, "Tiles folder written by `skyfall tile`")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", *out, "Output folder (DIR/scene)")->required();
  auto flags = std::make_shared<RunFlags>(cmd);
  flags->Add("--voxel-m", "merge.stitch.voxel_m");
  flags->Add("--lod-levels", "merge.lod.max_levels");
  cmd->callback([=] {
    *runner = [=] {
      const RunOptions options = flags->Resolve();
      options.Check();
      ConsoleProgress progress;
      const MergeSummary m = MergeTiles(*tiles, *out, options.merge, options.dsm, progress);
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

}  // namespace skyfall::cli
