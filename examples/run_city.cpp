// Synthesizes a small city and runs the whole pipeline on it through the
// library: skyfall_pipeline is all it links. Usage: run_city OUT_DIR
#include <cstdio>
#include <string>

#include "pipeline/city_run.h"
#include "testcity/testcity.h"

int main(int argc, char** argv) {
  if (argc != 2) return std::fprintf(stderr, "usage: run_city OUT_DIR\n"), 2;
  const std::string out = argv[1];
  skyfall::NullProgress progress;
  skyfall::synth::SynthOptions city;  // one 64 m block seen by 3 views
  city.size_m = 64;
  city.views = 3;
  skyfall::synth::RunSynth(city, out + "/input", progress);
  skyfall::RunOptions options;         // the product's defaults, shortened:
  options.train.optimizer.iterations = 60;
  options.train.init_max_scale_m = 0;  // few steps: let the initial Gaussians cover the gaps
  options.idu.options.orbit.episodes = 2;             // a short synthesis stage (where `auto` runs it)
  options.idu.options.iterations_per_episode = 20;
  options.executor.kind = skyfall::ExecutorKind::kInline;  // tiles in this process: no skyfall binary needed
  const skyfall::RunSummary run = skyfall::RunAll(options, {out + "/input", out + "/run", {}}, progress);
  for (const auto& c : run.cities)
    std::printf("%s: scene %s, DSM MAE %.2f m\n", c.city.c_str(), c.scene ? "yes" : "no",
                c.dsm_mae_m.empty() ? -1.0 : c.dsm_mae_m[0]);
  return run.exit_code;
}
