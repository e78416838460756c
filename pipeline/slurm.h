// The Slurm executor: a city's unfinished tiles go out as one `sbatch
// --array` job (one task per tile, each a `skyfall run-tile` process), and the
// city's merge, DSM export and reports as a second job that starts when every
// tile task succeeded (`--dependency=afterok`, running `skyfall finish-city`).
// The job scripts, the list of tiles and the job ids are written under
// OUT/<city>/slurm/, so `skyfall status OUT` and a rerun can find them.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "pipeline/run_options.h"

namespace skyfall {

// OUT/<city>/slurm/jobs.json: what was submitted last.
struct SlurmCityJobs {
  std::string tiles_job;            // array job id; empty when every tile was finished already
  std::string finish_job;           // merge + DSM job id
  std::vector<std::string> tiles;   // tile folders, in array task order
  std::string submitted_utc;
};

// Writes the two job scripts and submits them. `config_path` is the run
// configuration the tile and finish processes read. Throws Error naming the
// command and its message when sbatch refuses.
SlurmCityJobs SubmitSlurmCity(const RunOptions& options, const std::string& city_dir,
                              const std::vector<std::string>& unfinished_tiles, const std::string& config_path);

// Reads OUT/<city>/slurm/jobs.json; false when there is none.
bool ReadSlurmJobs(const std::string& city_dir, SlurmCityJobs* jobs);

// The scheduler's state of a job ("PENDING", "RUNNING", ...), with the
// reason of a pending job after a space ("PENDING DependencyNeverSatisfied");
// empty when the scheduler no longer lists it (finished). Array jobs give one
// entry per task index.
std::string SlurmJobState(const std::string& job_id);
std::map<int, std::string> SlurmArrayTaskStates(const std::string& array_job_id);

// Waits until the job leaves the queue, calling `on_poll` every `poll_s`.
// Returns "done" when it left the queue; "dependency_never_satisfied" when
// it can never start (a tile task failed; the job is then cancelled); or
// "held: ..." with the scheduler's reason when it or `watched_job` (the tile
// array) is held, e.g. after a launch that failed on the node (both are then
// cancelled).
std::string WaitForSlurmJob(const std::string& job_id, const std::string& watched_job, double poll_s,
                            const std::function<void()>& on_poll);

// The scheduler's reason when some task of the job is held; empty otherwise.
std::string HeldReason(const std::string& job_id);

// Runs a command (argv, no shell) and returns its exit code, with stdout and
// stderr in *output.
int RunProgram(const std::vector<std::string>& argv, std::string* output);

// A string as one single-quoted shell word.
std::string ShellQuote(const std::string& s);

}  // namespace skyfall
