// Adaptive density control of 3D Gaussian Splatting (clone small and split
// large Gaussians with large view-space gradients, prune transparent and
// huge ones) as a strategy with its own options, which the trainer calls
// after each backward pass and each step.
#pragma once

#include <cstddef>
#include <random>
#include <vector>

#include "core/gaussians.h"

namespace skyfall {

struct DensityControlOptions {
  int from_step = 500;       // first step that densifies
  int until_step = 2100;     // last step that adds Gaussians; pruning goes on one interval longer
  int interval_steps = 100;  // steps between densifications
  // Mean view-space gradient that triggers densification, in the 3DGS
  // reference's normalized device units (|dL/d(uv)| [1/px] times half the
  // image width), so the familiar 0.0002 keeps its meaning at any resolution.
  double grad_threshold = 0.0002;
  double percent_dense = 0.01;  // clone below, split above this fraction of the scene's extent
  double min_opacity = 0.005;   // pruned below
  double max_scale_m = 20.0;    // pruned above (paper: max covariance > 20)
  int max_gaussians = 2000000;
  void Check() const;  // throws Error("train", field, ...)
};

// The mean view-space gradient's sums since the last densification, per Gaussian.
struct DensifyStats {
  std::vector<float> grad_sum;
  std::vector<int> seen;
  void Reset(std::size_t n) {
    grad_sum.assign(n, 0.0f);
    seen.assign(n, 0);
  }
};

class DensityControl {
 public:
  // `extent_m`: the scene's extent, which scales the split size.
  DensityControl(const DensityControlOptions& options, double extent_m) : o_(options), extent_m_(extent_m) {}

  // After a view's backward pass: each Gaussian the view saw (radius_px > 0)
  // adds its view-space gradient norm, scaled by half the image width.
  void Accumulate(const std::vector<int>& radius_px, const std::vector<float>& mean2d_norm, int width_px);

  bool Due(int step) const;

  // Densifies `cloud` and its per-Gaussian companions (the optimizer's
  // moments, in the same layout) and puts them back in spatial order
  // (SpatialOrder); new split samples get zero moments for their centres.
  // Returns the source of each Gaussian kept or added, so that state kept
  // elsewhere follows. Resets the statistics.
  std::vector<std::size_t> Densify(int step, GaussianCloud* cloud, GaussianCloud* m, GaussianCloud* v,
                                   std::mt19937_64& rng);

  DensifyStats& stats() { return stats_; }
  const DensifyStats& stats() const { return stats_; }

 private:
  DensityControlOptions o_;
  double extent_m_;
  DensifyStats stats_;
};

// The Gaussians in the order of a Morton (Z-order) curve through their
// centres' x and y, as indices into `cloud`.
std::vector<std::size_t> SpatialOrder(const GaussianCloud& cloud);
GaussianCloud Gather(const GaussianCloud& cloud, const std::vector<std::size_t>& order);

}  // namespace skyfall
