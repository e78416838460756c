// `skyfall status OUT`: where a run stands, per city and tile, from the files
// the run wrote and, for the Slurm executor, from the scheduler.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace skyfall {

// {out, cities: [{city, state, tiles_done, tiles_total, slurm: {tiles_job,
// finish_job, finish_state} | null, tiles: [{tile, state, scheduler}]}]}.
// A tile's state is from its files: "ok", "degenerate", "skipped", "failed"
// (its tile_report.json), "started" (a run.log but no report: running, or
// killed), "waiting" (nothing yet). `scheduler` is its Slurm array task's
// state when the scheduler still lists it ("PENDING", "RUNNING"), else "".
// A city's state: "done" (run report with a scene), "failed" (a report
// without one), "running" (a Slurm finish job still queued) or "incomplete".
// Throws Error when OUT holds no run.
nlohmann::json RunStatus(const std::string& out_dir, bool ask_scheduler);

// The status as a table for people.
std::string RunStatusText(const nlohmann::json& status);

}  // namespace skyfall
