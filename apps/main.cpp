// skyfall: multi-view satellite imagery -> tiled 3D Gaussian-splat city scenes.
#include <spdlog/spdlog.h>

#include <csignal>
#include <functional>
#include <iostream>

#include "apps/commands.h"
#include "apps/console.h"
#include "core/allocator.h"
#include "core/error.h"
#include "core/simd.h"
#include "pipeline/event_log.h"
#include "pipeline/exit_codes.h"
#include "pipeline/tile_run.h"

namespace {

// The version and the SIMD path the kernels run on (core/simd.h).
std::string VersionText() {
  std::string paths;
  for (skyfall::SimdPath p : skyfall::SupportedSimdPaths()) paths += std::string(paths.empty() ? "" : ", ") + SimdPathName(p);
  std::string active;
  try {
    active = SimdPathName(skyfall::ActiveSimdPath());
  } catch (const skyfall::Error& e) {
    active = e.what();
  }
  return "skyfall " SKYFALL_VERSION "\nSIMD path: " + active + " (this CPU runs: " + paths + ")";
}

}  // namespace

int main(int argc, char** argv) {
  skyfall::DieWithParentIfAsked();  // a tile process of a killed run ends with it
  // A full disk or a file-size limit makes writes fail (EFBIG, ENOSPC) and
  // the atomic writers name the file, instead of the process being killed.
  signal(SIGXFSZ, SIG_IGN);
  skyfall::KeepFreedMemoryForReuse();
  CLI::App app{
      "skyfall " SKYFALL_VERSION
      ": batch tiler from multi-view satellite imagery (DFC2019 + RPC) to 3D Gaussian-splat "
      "city scenes with LOD and DSM exports"};
  app.set_version_flag("--version", std::function<std::string()>(VersionText));  // evaluated only for --version
  app.require_subcommand(1);
  bool quiet = false, verbose = false;
  app.add_flag("-q,--quiet", quiet, "Only warnings and errors on stderr");
  app.add_flag("-v,--verbose", verbose, "Debug detail on stderr");
  std::string log_json;
  app.add_option("--log-json", log_json,
                 "Also append machine-readable events to this file, one JSON object per line (time, level, stage, "
                 "aoi, tile, message, figures)");

  skyfall::cli::Runner runner;
  skyfall::cli::AddIngestCommand(app, &runner);
  skyfall::cli::AddRpcCommand(app, &runner);
  skyfall::cli::AddSynthCommand(app, &runner);
  skyfall::cli::AddSfmCommand(app, &runner);
  skyfall::cli::AddDenseCommand(app, &runner);
  skyfall::cli::AddSplatCommand(app, &runner);
  skyfall::cli::AddDsmCommand(app, &runner);
  skyfall::cli::AddReportCommand(app, &runner);
  skyfall::cli::AddTileCommands(app, &runner);
  skyfall::cli::AddRunCommand(app, &runner);
  skyfall::cli::AddFinishCityCommand(app, &runner);
  skyfall::cli::AddStatusCommand(app, &runner);
  skyfall::cli::AddExportCommand(app, &runner);
  skyfall::cli::AddViewCommand(app, &runner);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version end here with 0; every real parse error is a usage error.
    return app.exit(e) == 0 ? skyfall::kExitOk : skyfall::kExitUsage;
  }
  try {
    skyfall::cli::SetupLogging(quiet, verbose, log_json);
  } catch (const skyfall::Error& e) {
    std::cerr << e.what() << "\n";
    return skyfall::kExitBadInput;
  }
  try {
    return runner ? runner() : skyfall::kExitUsage;
  } catch (const skyfall::Error& e) {
    spdlog::error("{}", e.what());
    skyfall::cli::CliEventLog().Write({"error", "", "", "", e.what(), {}});
    return skyfall::kExitBadInput;
  } catch (const std::exception& e) {
    spdlog::error("internal error: {}", e.what());
    return skyfall::kExitInternal;
  }
}
