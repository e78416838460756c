// Command-line flags that set fields of a RunOptions. The effective options
// are the library defaults, then a --config file, then --set assignments,
// then the flags actually given, so a flag always wins over the file.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "pipeline/run_options.h"

namespace skyfall::cli {

class RunFlags {
 public:
  // Registers --config and --set on `cmd`.
  explicit RunFlags(CLI::App* cmd);

  // A flag that sets the option at `path` (dotted, as --set takes it). Its
  // help, unit and default come from the option registry, so a flag is
  // described where its option is. Returns the option for further checks.
  CLI::Option* Add(const std::string& name, const std::string& path);

  // The per-tile flags shared by `run` and `run-tile`.
  void AddTileFlags();

  // The effective options (not yet checked).
  RunOptions Resolve();

 private:
  CLI::App* cmd_;
  std::string config_path_;
  std::vector<std::string> assignments_;
  struct Flag {
    CLI::Option* option;
    std::string path;
    std::shared_ptr<std::string> value;  // CLI11 writes the flag's text here
  };
  std::vector<Flag> flags_;
};

}  // namespace skyfall::cli
