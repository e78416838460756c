// skyfall: multi-view satellite imagery -> tiled 3D Gaussian-splat city scenes.
#include <spdlog/spdlog.h>

#include <iostream>

#include "apps/commands.h"
#include "apps/console.h"
#include "core/error.h"

int main(int argc, char** argv) {
  CLI::App app{
      "skyfall " SKYFALL_VERSION
      ": batch tiler from multi-view satellite imagery (DFC2019 + RPC) to 3D Gaussian-splat "
      "city scenes with LOD and DSM exports"};
  app.set_version_flag("--version", "skyfall " SKYFALL_VERSION);
  app.require_subcommand(1);
  bool quiet = false, verbose = false;
  app.add_flag("-q,--quiet", quiet, "Only warnings and errors on stderr");
  app.add_flag("-v,--verbose", verbose, "Debug detail on stderr");

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

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  skyfall::cli::SetupLogging(quiet, verbose);
  try {
    return runner ? runner() : 2;
  } catch (const skyfall::Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  } catch (const std::exception& e) {
    spdlog::error("internal error: {}", e.what());
    return 3;
  }
}
