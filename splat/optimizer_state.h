// The trainer's optimizer state and its checkpoint file (not a public
// header): Adam's moments in the cloud's own layout, the appearance model
// with its moments, and the binary checkpoint that holds them with the
// cloud, the random state and the series.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/gaussians.h"
#include "splat/appearance.h"
#include "splat/density_control.h"
#include "splat/trainer.h"

namespace skyfall {

// Adam moments in the cloud's own layout.
struct Adam {
  GaussianCloud m, v;
  long step = 0;
  void Resize(std::size_t n) {
    for (GaussianCloud* c : {&m, &v}) {
      const std::size_t old = c->size();
      c->resize(n);
      for (std::size_t i = old; i < n; ++i) {
        c->means[i].setZero();
        c->log_scales[i].setZero();
        c->rotations[i].setZero();
        c->opacity_logits[i] = 0;
        c->sh[i].fill(0);
      }
    }
  }
};

// The appearance model with its Adam moments.
struct AppearanceState {
  bool enabled = false;
  AppearanceModel model, m, v;
};

// One Adam step on every Gaussian field (the centres at `lr_mean`, the
// others at their options' rates), and one on the appearance model.
void AdamStep(GaussianCloud& c, Adam& adam, const GaussianCloud& g, const TrainOptions& o, double lr_mean);
void AdamStepAppearance(AppearanceState& a, AppearanceModel& grad, long step, const AppearanceOptions& o);

struct Checkpoint {
  int iteration = 0;
  GaussianCloud cloud;
  Adam adam;
  std::string rng_state;
  std::vector<TrainSample> series;
  DensifyStats stats;        // gradient statistics since the last densification
  double loss_sum = 0;       // training loss since the last series sample
  std::int64_t loss_count = 0;
  AppearanceState appearance;
};

void SaveCheckpoint(const std::string& path, const Checkpoint& ck);
// Throws Error("train", path, ...) for a file that is not a checkpoint or
// does not hold together.
Checkpoint LoadCheckpoint(const std::string& path);

}  // namespace skyfall
