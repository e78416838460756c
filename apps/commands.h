// Each subcommand registers its options on the CLI11 app and returns the exit
// code when run. Errors are thrown as skyfall::Error and reported by main.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <memory>
#include <string>

#include "core/enum_codec.h"
#include "pipeline/exit_codes.h"

namespace skyfall::cli {

// Called after parsing when the subcommand was chosen; returns the exit code.
using Runner = std::function<int()>;

// An option whose value is one of a mode's names (EnumNames<E>), written
// into `*mode`; its default shown in --help is `*mode`'s name.
template <class E>
CLI::Option* AddModeOption(CLI::App* cmd, const std::string& name, E* mode, const std::string& help) {
  auto text = std::make_shared<std::string>(EnumName(*mode));
  CLI::Option* option = cmd->add_option(name, *text, help)->check(CLI::IsMember(EnumNameList<E>()));
  option->default_str(*text);
  option->each([mode, text](const std::string& value) { *mode = *EnumFromName<E>(value); });
  return option;
}

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
