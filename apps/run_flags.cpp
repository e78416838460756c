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

void RunFlags::AddTileFlags() {
  Add("--iterations", +[](RunOptions& o) -> int& { return o.train.optimizer.iterations; }, "Splat training steps per tile");
  Add("--resolution", +[](RunOptions& o) -> int& { return o.train.downscale; }, "Training image downscale factor");
  Add("--depth-prior", +[](RunOptions& o) -> std::string& { return o.train.depth_prior; },
      "Pseudo-camera depth prior: 'surface', 'none' or 'cmd:COMMAND' (see splat train)");
  Add("--appearance", +[](RunOptions& o) -> std::string& { return o.train.appearance; },
      "Per-image appearance model: 'auto' (on for multi-date views), 'on' or 'off'")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  Add("--init-max-scale", +[](RunOptions& o) -> double& { return o.train.init_max_scale_m; },
      "Cap on the initial Gaussian size [m] (0 = none)");
  Add("--init-pieces", +[](RunOptions& o) -> int& { return o.train.init_pieces; },
      "Up to this many capped Gaussians per tie point");
  Add("--init-points", +[](RunOptions& o) -> std::string& { return o.train.init_points; },
      "Initial Gaussians from 'dense' heights, 'sparse' tie points (no dense stage) or 'auto'")
      ->check(CLI::IsMember({"auto", "dense", "sparse"}));
  Add("--densify", +[](RunOptions& o) -> std::string& { return o.train.densify; },
      "Clone/split/prune: 'on', 'off' or 'auto' (off for dense starts)")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  Add("--idu", +[](RunOptions& o) -> std::string& { return o.idu.mode; },
      "Synthesis stage (curriculum IDU): 'auto' (where the dense heights show facades), 'on' or 'off'")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  Add("--refiner", +[](RunOptions& o) -> std::string& { return o.idu.refiner; },
      "IDU refiner: 'reproject' (built in) or 'cmd:COMMAND' (e.g. a FlowEdit script; see README)");
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
  for (auto& [option, copy] : given_) {
    if (option->count() > 0) copy(options, scratch_);
  }
  return options;
}

}  // namespace skyfall::cli
