// skyfall run ROOT --out OUT: the whole batch for every AOI of a DFC2019 tree.
#include <spdlog/spdlog.h>

#include <iostream>

#include "apps/commands.h"
#include "apps/console.h"
#include "apps/run_flags.h"
#include "core/error.h"
#include "pipeline/city_run.h"
#include "pipeline/exit_codes.h"
#include "pipeline/run_status.h"

namespace skyfall::cli {

void AddRunCommand(CLI::App& app, Runner* runner) {
  auto request = std::make_shared<RunRequest>();
  auto print_config = std::make_shared<bool>(false);
  auto print_reference = std::make_shared<bool>(false);
  auto tiles3d = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "run", "The whole pipeline for every AOI of a DFC2019 tree: ingest, tile, per-tile SfM, dense heights and splat "
             "training, merge with LOD, DSM export and comparison with the truth; resumable");
  auto flags = std::make_shared<RunFlags>(cmd);
  cmd->add_option("root", request->root, "DFC2019 root folder")->check(CLI::ExistingDirectory);
  cmd->add_option("--out", request->out, "Output folder: OUT/<city>/{tiles,scene,run_report.json}, OUT/<AOI>/dsm*");
  cmd->add_option("--aoi", request->aois, "Only these AOIs (repeatable)");
  cmd->add_option("--wait-lock", request->wait_lock_s,
                  "When another run holds OUT's lock, wait up to this many seconds for it (default: exit at once "
                  "with code 7)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--3dtiles", *tiles3d,
                "Also export each city as 3D Tiles 1.1 with SPZ Gaussian splats into OUT/<city>/3dtiles "
                "(exports.tiles3d)");
  cmd->add_flag("--print-config", *print_config,
                "Print the effective configuration (defaults, --config, --set, flags) as JSON and exit");
  cmd->add_flag("--print-options-reference", *print_reference,
                "Print every option of the run configuration (path, type, default, unit, meaning) as the Markdown "
                "tables of docs/cli.md and exit");
  flags->Add("--tile-m", "tiling.tile_m");
  flags->Add("--tile-cells", "tiling.tile_cells");
  flags->Add("--overlap-m", "tiling.overlap_m");
  flags->AddTileFlags();
  flags->Add("--jobs", "executor.jobs");
  flags->Add("--executor", "executor.kind");
  flags->Add("--slurm-partition", "executor.slurm.partition");
  flags->Add("--slurm-account", "executor.slurm.account");
  flags->Add("--slurm-time", "executor.slurm.time_limit");
  flags->Add("--slurm-cpus", "executor.slurm.cpus_per_task");
  flags->Add("--slurm-mem-mb", "executor.slurm.mem_mb");
  cmd->callback([runner, request, print_config, print_reference, flags, tiles3d] {
    *runner = [request, print_config, print_reference, flags, tiles3d] {
      if (*print_reference) {
        std::cout << RunOptionsReferenceMarkdown();
        return kExitOk;
      }
      RunOptions options = flags->Resolve();
      if (*tiles3d) options.exports.tiles3d = true;
      options.Check();  // every field and mode, before any stage runs
      if (*print_config) {
        std::cout << RunOptionsToJson(options);
        return kExitOk;
      }
      if (request->root.empty()) throw Error("run", "ROOT", "is required (only --print-config runs without it)");
      if (request->out.empty()) throw Error("run", "--out", "is required (only --print-config runs without it)");
      ConsoleProgress progress;
      const RunSummary summary = RunAll(options, *request, progress);
      if (summary.exit_code == kExitLocked) {
        spdlog::error("run: {} is in use by another run ({}); try later or pass --wait-lock SECONDS", request->out,
                      summary.lock_holder);
      }
      return summary.exit_code;
    };
  });
}

void AddFinishCityCommand(CLI::App& app, Runner* runner) {
  auto city_dir = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "finish-city", "Merge with LOD, DSM export and comparison, run report and STAC catalog of a city whose tiles "
                     "have run (what the Slurm executor's second job runs)");
  cmd->add_option("city_dir", *city_dir, "OUT/<city>, holding city_job.json and run_config.json")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->callback([=] {
    *runner = [=] {
      ConsoleProgress progress;
      const CityOutcome city = FinishCityFromFiles(*city_dir, progress);
      if (!city.scene) {
        spdlog::error("finish-city {}: {}", *city_dir, city.error);
        return kExitNothingDone;
      }
      return city.tiles_failed > 0 ? kExitPartial : kExitOk;
    };
  });
}

void AddStatusCommand(CLI::App& app, Runner* runner) {
  auto out = std::make_shared<std::string>();
  auto as_json = std::make_shared<bool>(false);
  auto no_scheduler = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "status", "Where a run stands: per city and tile, from its files and, for the Slurm executor, the scheduler");
  cmd->add_option("out", *out, "Output folder of `skyfall run`")->required()->check(CLI::ExistingDirectory);
  cmd->add_flag("--json", *as_json, "Print the status as JSON on stdout");
  cmd->add_flag("--no-scheduler", *no_scheduler, "Do not ask Slurm (files only)");
  cmd->callback([=] {
    *runner = [=] {
      const nlohmann::json status = RunStatus(*out, !*no_scheduler);
      std::cout << (*as_json ? status.dump(2) + "\n" : RunStatusText(status));
      return kExitOk;
    };
  });
}

}  // namespace skyfall::cli
