// One training step at the reference size (100k Gaussians, 512x384), split
// into its phases: what scripts/bench.sh reports as step_ms and its parts.
// The step is the real one (TrainGaussians with the defaults of `skyfall
// run`: surface anchor with its nadir patches, pseudo views, the appearance
// model when on), on 8 oblique views of the reference scene whose targets
// are renders of a second, different cloud.
//
// Usage: step_bench [--steps N] [--gaussians N] [--appearance mlp|bilinear|off]
// Prints one JSON object on stdout.
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>

#include "bench/bench_scene.h"
#include "core/allocator.h"
#include "core/stage.h"
#include "splat/depth_prior.h"
#include "splat/rasterizer.h"
#include "splat/trainer.h"

namespace skyfall {
namespace {

struct BenchArgs {
  int steps = 40;
  int gaussians = 100000;
  std::string appearance = "mlp";
};

BenchArgs ParseArgs(int argc, char** argv) {
  BenchArgs a;
  for (int k = 1; k + 1 < argc; k += 2) {
    const std::string key = argv[k], value = argv[k + 1];
    if (key == "--steps") {
      a.steps = std::atoi(value.c_str());
    } else if (key == "--gaussians") {
      a.gaussians = std::atoi(value.c_str());
    } else if (key == "--appearance") {
      if (value != "mlp" && value != "bilinear" && value != "off")
        throw std::runtime_error("step_bench: --appearance takes mlp, bilinear or off");
      a.appearance = value;
    } else {
      throw std::runtime_error("step_bench: unknown option " + key);
    }
  }
  if (a.steps < 1 || a.gaussians < 1) throw std::runtime_error("step_bench: --steps and --gaussians must be >= 1");
  return a;
}

std::vector<TrainView> BenchViews(int gaussians) {
  const GaussianCloud target = BenchCloud(gaussians, 8);
  std::vector<TrainView> views;
  for (int k = 0; k < 8; ++k) {
    TrainView v;
    v.name = "view_" + std::to_string(k);
    v.camera = BenchCamera(45.0 * k);
    v.rgb = RenderGaussians(target, v.camera, RasterOptions{}).rgb;
    v.acquisition_time = "2020-01-0" + std::to_string(1 + k % 8) + "T16:00:00Z";
    views.push_back(std::move(v));
  }
  return views;
}

int Main(int argc, char** argv) {
  KeepFreedMemoryForReuse();  // as the skyfall binary does
  const BenchArgs args = ParseArgs(argc, argv);
  const GaussianCloud cloud = BenchCloud(args.gaussians);
  const std::vector<TrainView> views = BenchViews(args.gaussians);
  SurfaceDepthPrior surface(cloud.means, 1.0);
  TrainOptions o;
  o.iterations = args.steps;
  o.eval_interval = 1000000;      // the one evaluation at the end is excluded below
  o.density.from_step = 1000000;       // densification is not part of a step
  o.appearance.enabled = args.appearance != "off";
  if (o.appearance.enabled) o.appearance.model = *EnumFromName<AppearanceModelKind>(args.appearance);  // checked above
  NullProgress progress;
  const TrainResult r = TrainGaussians(o, cloud, views, "", progress, &surface, &surface);
  const StepProfile& p = r.profile;
  nlohmann::json out = {{"gaussians", args.gaussians},
                        {"width_px", kWidth},
                        {"height_px", kHeight},
                        {"steps", p.steps},
                        {"appearance_model", args.appearance}};
  // The final held-out evaluation happens once per run, not per step.
  double step_ms = 0;
  for (int k = 0; k < StepProfile::kCount; ++k) {
    const std::string phase = StepProfile::kPhases[k];
    if (phase == "evaluation") continue;
    out[phase + "_ms"] = p.MeanMs(k);
    step_ms += p.MeanMs(k);
  }
  out["step_ms"] = step_ms;
  std::cout << out.dump(2) << "\n";
  return 0;
}

}  // namespace
}  // namespace skyfall

int main(int argc, char** argv) {
  try {
    return skyfall::Main(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\n";
    return 1;
  }
}
