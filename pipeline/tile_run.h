// One tile's pipeline (SfM, dense heights, splat training) and the executors
// that run a city's tiles: as separate `skyfall run-tile` processes (memory
// and crash isolation; several at once) or one after the other in this
// process.
#pragma once

#include <string>
#include <vector>

#include "core/stage.h"
#include "pipeline/run_options.h"

namespace skyfall {

// Runs one tile folder written by WriteTiles (`skyfall tile`) with the SfM,
// dense and training options of `options`. Resumable: a tile whose
// tile_report.json says it finished under the same options is skipped; a
// killed one redoes SfM unless its report was written, reuses finished dense
// heights, and resumes training from its checkpoint. Writes
// DIR/tile_report.json last. `threads` caps TBB's threads (0 = all cores).
StageReport RunTile(const std::string& tile_dir, const RunOptions& options, int threads, Progress& progress);

struct TileOutcome {
  std::string dir;
  int exit_code = 0;     // as `skyfall run-tile` exits (see exit_codes.h)
  double seconds = 0;
  std::string message;   // why it failed (the end of DIR/run.log for a process)
};

// Environment variable the local executor gives its tile processes: the
// parent's PID. A process that finds it asks the kernel to kill it when the
// parent dies (and exits at once when the parent is already gone).
inline constexpr const char* kParentPidEnv = "SKYFALL_PARENT_PID";

// Call first in a process that may be a tile process (see kParentPidEnv).
void DieWithParentIfAsked();

// How many tiles run at once: at most `requested` (0 = number of cores),
// cores, and what the available memory allows given an estimate per tile.
int ParallelTileJobs(const std::vector<std::string>& tile_dirs, int requested, std::string* why);

// Runs every tile folder with options.executor. One failing tile never stops
// the others. With "local", `config_path` is the run configuration file the
// child processes read (written by the caller); each child logs to DIR/run.log.
std::vector<TileOutcome> RunTiles(const std::vector<std::string>& tile_dirs, const RunOptions& options,
                                  const std::string& config_path, Progress& progress);

// [MB] the memory a tile run is estimated to need (from its crops' pixels).
double EstimatedTileMemoryMb(const std::string& tile_dir);

// The skyfall executable tile processes and jobs run (see ExecutorOptions::program).
std::string TileProgramPath(const ExecutorOptions& executor);

// True when the tile's report says it finished (ok, degenerate or skipped)
// under these options, so a rerun or a resubmission leaves it alone.
bool TileFinished(const std::string& tile_dir, const RunOptions& options);

// How a tile run by someone else (a Slurm job) ended, from its tile_report.json.
TileOutcome TileOutcomeFromReport(const std::string& tile_dir);

}  // namespace skyfall
