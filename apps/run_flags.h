// Command-line flags that set fields of a RunOptions. The effective options
// are the library defaults, then a --config file, then --set assignments,
// then the flags actually given, so a flag always wins over the file.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "pipeline/run_options.h"

namespace skyfall::cli {

class RunFlags {
 public:
  // Registers --config and --set on `cmd`.
  explicit RunFlags(CLI::App* cmd);

  // A flag bound to the field `field` returns; its default shown in --help is
  // the library's. Returns the option for further checks.
  template <class T>
  CLI::Option* Add(const std::string& name, T& (*field)(RunOptions&), const std::string& help) {
    CLI::Option* option = cmd_->add_option(name, field(scratch_), help)->capture_default_str();
    given_.emplace_back(option, [field](RunOptions& to, RunOptions& from) { field(to) = field(from); });
    return option;
  }

  // The per-tile flags shared by `run` and `run-tile`.
  void AddTileFlags();

  // The effective options (not yet checked).
  RunOptions Resolve();

 private:
  CLI::App* cmd_;
  RunOptions scratch_;  // CLI11 writes the flags' values here
  std::string config_path_;
  std::vector<std::string> assignments_;
  std::vector<std::pair<CLI::Option*, std::function<void(RunOptions&, RunOptions&)>>> given_;
};

}  // namespace skyfall::cli
