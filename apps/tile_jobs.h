// The per-tile pipeline (SfM then splat training), the parallel driver that
// runs tiles as separate processes, and the merge of a city's tiles.
#pragma once

#include <string>
#include <vector>

#include "apps/jobs.h"
#include "core/stage.h"
#include "merge/lod.h"
#include "merge/seam.h"
#include "merge/stitch.h"

namespace skyfall::cli {

struct TileRunOptions {
  int iterations = 1000;                // splat training steps per tile
  int downscale = 2;                    // image downscale for training (SfM uses full resolution)
  std::string depth_prior = "surface";  // see `skyfall splat train --depth-prior`
  std::string appearance = "auto";      // see `skyfall splat train --appearance`
  double init_max_scale_m = TrainJob{}.init_max_scale_m;  // see `skyfall splat train --init-max-scale`
  int init_pieces = TrainJob{}.init_pieces;               // see `skyfall splat train --init-pieces`
  std::string init_points = TrainJob{}.init_points;       // see `skyfall splat train --init-points`; "sparse" skips the dense stage
  int threads = 0;                      // TBB threads in this tile (0 = all cores)
};

// Runs one tile folder written by `skyfall tile`. Resumable: a tile whose
// tile_report.json says it finished with the same options is skipped; a
// killed one redoes SfM unless its report was written and resumes training
// from its checkpoint. Writes DIR/tile_report.json last.
StageReport RunTile(const std::string& tile_dir, const TileRunOptions& options, Progress& progress);

// Exit code of `skyfall run-tile` for a report (0 ok or skipped, 4 degenerate).
int TileExitCode(const StageReport& report);

}  // namespace skyfall::cli
namespace CLI { class App; }
namespace skyfall::cli {
// The per-tile options on a command line (shared by run-tile and run).
void AddRunTileOptionsTo(CLI::App* cmd, TileRunOptions* options);

struct TileOutcome {
  std::string dir;
  int exit_code = 0;
  double seconds = 0;
  std::string message;  // last lines of DIR/run.log when it failed
};

// How many tiles run at once: at most `requested` (0 = number of cores),
// cores, and what the available memory allows given an estimate per tile.
int ParallelTileJobs(const std::vector<std::string>& tile_dirs, int requested, std::string* why);

// Runs `skyfall run-tile` for every folder, `jobs` processes at a time, each
// logging to DIR/run.log. One failing tile never stops the others.
std::vector<TileOutcome> RunTilesInParallel(const std::vector<std::string>& tile_dirs, const TileRunOptions& options,
                                            int jobs, Progress& progress);

struct MergeOptions {
  StitchOptions stitch;
  LodOptions lod;
  double seam_gsd_m = 0.5;  // [m] DSM spacing of the seam metric
};

struct MergeSummary {
  std::string scene_path;
  GeodeticPoint enu_origin;
  int epsg = 0;
  std::size_t tiles_merged = 0, tiles_missing = 0;
  SeamMetric seam;
  StageReport report;
};

// Merges the finished tiles of OUT/tiles (tiles.json) into out_dir:
// scene.ply, lod_<k>.ply + lod.json, frame.json, dsm_city.tif and
// merge_report.json (stitch counts, seam metric, LOD levels).
MergeSummary MergeTiles(const std::string& tiles_dir, const std::string& out_dir, const MergeOptions& options,
                        Progress& progress);

}  // namespace skyfall::cli
