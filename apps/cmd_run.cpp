// skyfall run ROOT --out OUT: the whole batch for every AOI of a DFC2019 tree.
#include <iostream>

#include "apps/commands.h"
#include "apps/console.h"
#include "apps/run_flags.h"
#include "core/error.h"
#include "pipeline/city_run.h"
#include "pipeline/exit_codes.h"

namespace skyfall::cli {

void AddRunCommand(CLI::App& app, Runner* runner) {
  auto request = std::make_shared<RunRequest>();
  auto print_config = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "run", "The whole pipeline for every AOI of a DFC2019 tree: ingest, tile, per-tile SfM, dense heights and splat "
             "training, merge with LOD, DSM export and comparison with the truth; resumable");
  auto flags = std::make_shared<RunFlags>(cmd);
  cmd->add_option("root", request->root, "DFC2019 root folder")->check(CLI::ExistingDirectory);
  cmd->add_option("--out", request->out, "Output folder: OUT/<city>/{tiles,scene,run_report.json}, OUT/<AOI>/dsm*");
  cmd->add_option("--aoi", request->aois, "Only these AOIs (repeatable)");
  cmd->add_flag("--print-config", *print_config,
                "Print the effective configuration (defaults, --config, --set, flags) as JSON and exit");
  flags->Add("--tile-m", +[](RunOptions& o) -> double& { return o.tiling.tile_m; }, "Tile core side [m]");
  flags->Add("--overlap-m", +[](RunOptions& o) -> double& { return o.tiling.overlap_m; }, "Overlap margin [m]");
  flags->AddTileFlags();
  flags->Add("--jobs", +[](RunOptions& o) -> int& { return o.executor.jobs; },
             "Tiles run at once (0 = bounded by cores and memory)");
  flags->Add("--executor", +[](RunOptions& o) -> std::string& { return o.executor.kind; },
             "'local' (each tile its own process) or 'inline' (tiles in this process, one at a time)")
      ->check(CLI::IsMember({"local", "inline"}));
  cmd->callback([runner, request, print_config, flags] {
    *runner = [request, print_config, flags] {
      const RunOptions options = flags->Resolve();
      options.Check();  // every field and mode, before any stage runs
      if (*print_config) {
        std::cout << RunOptionsToJson(options);
        return kExitOk;
      }
      if (request->root.empty()) throw Error("run", "ROOT", "is required (only --print-config runs without it)");
      if (request->out.empty()) throw Error("run", "--out", "is required (only --print-config runs without it)");
      ConsoleProgress progress;
      return RunAll(options, *request, progress).exit_code;
    };
  });
}

}  // namespace skyfall::cli
