// Adaptive density control of 3D Gaussian Splatting (clone small and split
// large Gaussians with large view-space gradients, prune transparent and
// huge ones) as a strategy with its own options, which the trainer calls
// after each backward pass and each step.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <random>
#include <vector>

#include "core/gaussians.h"
#include "core/option_range.h"

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
  // Coincident Gaussians: centres closer than `merge_within_m` whose
  // covariances differ by at most `merge_max_shape_difference` (relative
  // Frobenius norm) are merged into one every `merge_interval_steps` steps,
  // except on the last step, whatever densification does. Without it a
  // third of a dense start's Gaussians end up as copies of a neighbour
  // (decisions D-123, D-124). 0 = off.
  double merge_within_m = 0.01;
  int merge_interval_steps = 100;
  double merge_max_shape_difference = 0.25;
  void Check() const;  // throws Error("train", field, ...)
};

// As the run lists them (train.* in run_config.json).
template <class IO> void Visit(IO& io, DensityControlOptions& d) {
  io("densify_from", d.from_step,
     "First step of adaptive density control (clone, split, prune)", range::AtLeast(0));
  io("densify_until", d.until_step,
     "Last step that adds Gaussians by cloning or splitting", range::AtLeast(0));
  io("densify_interval", d.interval_steps,
     "Steps between densification passes", range::AtLeast(1));
  io("densify_grad_threshold", d.grad_threshold,
     "Mean view-space gradient of a Gaussian's centre above which it is cloned or split, in the 3DGS reference's "
     "normalized units", range::Above(0));
  io("percent_dense", d.percent_dense,
     "Gaussians smaller than this fraction of the scene extent are cloned, larger ones split", range::AboveUpTo(0, 1));
  io("min_opacity", d.min_opacity,
     "Gaussians more transparent than this are pruned", range::FromBelow(0, 1));
  io("max_scale_m", d.max_scale_m,
     "Gaussians larger than this are pruned", range::Above(0));
  io("max_gaussians", d.max_gaussians,
     "Densification adds no Gaussians beyond this count", range::AtLeast(1));
  io("merge_within_m", d.merge_within_m,
     "Gaussians whose centres are closer than this and whose shapes are alike are merged into one, every "
     "merge_interval steps (0 = off)", range::AtLeast(0));
  io("merge_interval", d.merge_interval_steps,
     "Steps between merges of coincident Gaussians; none on the last step", range::AtLeast(1));
  io("merge_max_shape_difference", d.merge_max_shape_difference,
     "Coincident Gaussians merge only when their covariances differ by at most this fraction (relative Frobenius "
     "norm)", range::AtLeast(0));
}

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

  // Whether step `step` of `iterations` merges coincident Gaussians.
  bool MergeDue(int step, int iterations) const;

  // Merges coincident Gaussians (see DensityControlOptions) in `cloud`:
  // each group becomes one Gaussian at the group's opacity-weighted centre,
  // with its opacity 1 - prod(1 - opacity), the opacity-weighted colour and
  // the moment-matched covariance, in the first member's place. The
  // optimizer's moments and the gradient statistics are the most opaque
  // member's. Returns the source of each Gaussian kept (that member).
  std::vector<std::size_t> MergeCoincident(GaussianCloud* cloud, GaussianCloud* m, GaussianCloud* v);

  DensifyStats& stats() { return stats_; }
  const DensifyStats& stats() const { return stats_; }

 private:
  DensityControlOptions o_;
  double extent_m_;
  DensifyStats stats_;
};

// Centres hashed to cubes of a radius, to find the centres within it of a
// point: such a centre lies in one of the 27 cubes around the point's own.
class CentreGrid {
 public:
  CentreGrid(const GaussianCloud& cloud, double within_m);
  // Calls fn(j) for each Gaussian j != i whose centre is closer than the
  // radius to Gaussian i's; stops when fn returns false.
  template <typename Fn>
  void ForEachNear(std::size_t i, Fn&& fn) const;

 private:
  using Key = std::array<std::int64_t, 3>;
  Key KeyOf(const Eigen::Vector3f& p) const;
  const GaussianCloud& cloud_;
  double within_m_;
  std::map<Key, std::vector<std::uint32_t>> cubes_;
};

template <typename Fn>
void CentreGrid::ForEachNear(std::size_t i, Fn&& fn) const {
  const Key k = KeyOf(cloud_.means[i]);
  const double within2 = within_m_ * within_m_;
  for (std::int64_t dx = -1; dx <= 1; ++dx)
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        const auto it = cubes_.find(Key{k[0] + dx, k[1] + dy, k[2] + dz});
        if (it == cubes_.end()) continue;
        for (std::uint32_t j : it->second)
          if (j != i && (cloud_.means[j] - cloud_.means[i]).cast<double>().squaredNorm() < within2 && !fn(j)) return;
      }
}

// The Gaussians in the order of a Morton (Z-order) curve through their
// centres' x and y, as indices into `cloud`.
std::vector<std::size_t> SpatialOrder(const GaussianCloud& cloud);
GaussianCloud Gather(const GaussianCloud& cloud, const std::vector<std::size_t>& order);

}  // namespace skyfall
