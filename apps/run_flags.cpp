#include "apps/run_flags.h"

#include <iostream>
#include <iterator>

#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall::cli {

RunFlags::RunFlags(CLI::App* cmd) : cmd_(cmd) {
  cmd->add_option("--config", config_path_,
                  "Run configuration (JSON, as --print-config writes it; '-' reads standard input); flags override it");
  cmd->add_option("--set", assignments_,
                  "Set any option by its path, e.g. --set dense.sgm_p2=1.5 (repeatable; see --print-config)");
}

CLI::Option* RunFlags::Add(const std::string& name, const std::string& path) {
  const OptionDescription d = DescribeRunOption(path);
  auto value = std::make_shared<std::string>();
  const std::string unit = d.unit.empty() ? "" : " [" + d.unit + "]";
  const std::string range = d.range.Declared() ? ", " + d.range.Text() : "";
  CLI::Option* option = cmd_->add_option(name, *value, d.help + unit + " (" + path + range + ")");
  const bool quoted = d.default_json.size() >= 2 && d.default_json.front() == '"';
  option->default_str(quoted ? d.default_json.substr(1, d.default_json.size() - 2) : d.default_json);
  option->type_name(d.type == "integer" ? "INT" : d.type == "number" ? "FLOAT" : "TEXT");
  if (!d.choices.empty()) option->check(CLI::IsMember(d.choices));
  flags_.push_back({option, path, value});
  return option;
}

void RunFlags::AddTileFlags() {
  Add("--iterations", "train.iterations");
  Add("--resolution", "train.downscale");
  Add("--depth-prior", "train.depth_prior");
  Add("--appearance", "train.appearance");
  Add("--init-max-scale", "train.init_max_scale_m");
  Add("--init-pieces", "train.init_pieces");
  Add("--init-points", "train.init_points");
  Add("--densify", "train.densify");
  Add("--idu", "idu.mode");
  Add("--refiner", "idu.refiner");
}

RunOptions RunFlags::Resolve() {
  RunOptions options;
  if (!config_path_.empty()) {
    std::string text;
    if (config_path_ == "-") {
      text.assign(std::istreambuf_iterator<char>(std::cin), std::istreambuf_iterator<char>());
    } else {
      text = ReadTextFile(config_path_);
    }
    options = RunOptionsFromJson(text, config_path_ == "-" ? "standard input" : config_path_);
  }
  for (const std::string& a : assignments_) SetRunOption(&options, a);
  for (const Flag& flag : flags_) {
    if (flag.option->count() == 0) continue;
    try {
      SetRunOption(&options, flag.path + "=" + *flag.value);
    } catch (const Error& e) {
      throw Error("run", flag.option->get_name(), e.detail());
    }
  }
  return options;
}

}  // namespace skyfall::cli
