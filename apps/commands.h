// Each subcommand registers its options on the CLI11 app and returns the exit
// code when run. Errors are thrown as skyfall::Error and reported by main.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

#include "pipeline/exit_codes.h"

namespace skyfall::cli {

// Called after parsing when the subcommand was chosen; returns the exit code.
using Runner = std::function<int()>;

void AddIngestCommand(CLI::App& app, Runner* runner);
void AddRpcCommand(CLI::App& app, Runner* runner);
void AddSynthCommand(CLI::App& app, Runner* runner);
void AddSfmCommand(CLI::App& app, Runner* runner);
void AddDenseCommand(CLI::App& app, Runner* runner);
void AddSplatCommand(CLI::App& app, Runner* runner);
void AddDsmCommand(CLI::App& app, Runner* runner);
void AddReportCommand(CLI::App& app, Runner* runner);
void AddTileCommands(CLI::App& app, Runner* runner);  // tile, run-tile, merge
void AddRunCommand(CLI::App& app, Runner* runner);
void AddFinishCityCommand(CLI::App& app, Runner* runner);
void AddStatusCommand(CLI::App& app, Runner* runner);
void AddExportCommand(CLI::App& app, Runner* runner);
void AddViewCommand(CLI::App& app, Runner* runner);

}  // namespace skyfall::cli
