// Shared by the splat tests that compare analytic gradients with central
// differences, or the SIMD paths with each other.
#pragma once

#include "core/simd.h"
#include "splat/rasterizer.h"

namespace skyfall::testing {

// Switches the SIMD path for one scope, then back.
class ScopedSimdPath {
 public:
  explicit ScopedSimdPath(SimdPath p) : previous_(ActiveSimdPath()) { SetSimdPath(p); }
  ~ScopedSimdPath() { SetSimdPath(previous_); }
  ScopedSimdPath(const ScopedSimdPath&) = delete;
  ScopedSimdPath& operator=(const ScopedSimdPath&) = delete;

 private:
  SimdPath previous_;
};

// Options that make the rendered image a smooth function of the parameters,
// so central differences are meaningful: no alpha cut-off, no early stop, and
// footprints wide enough that the tile cut-off is below 1e-14.
inline RasterOptions SmoothRasterOptions() {
  RasterOptions o;
  o.min_alpha = 0.0;
  o.min_transmittance = 0.0;
  o.sigma_extent = 8.0;
  o.background = Eigen::Vector3d(0.2, 0.3, 0.4);
  return o;
}

// The same cloud in float (the precision training runs in).
inline GaussianCloudT<float> ToFloat(const GaussianCloudT<double>& d) {
  GaussianCloudT<float> c;
  c.resize(d.size());
  for (std::size_t i = 0; i < d.size(); ++i) {
    c.means[i] = d.means[i].cast<float>();
    c.log_scales[i] = d.log_scales[i].cast<float>();
    c.rotations[i] = d.rotations[i].cast<float>();
    c.opacity_logits[i] = static_cast<float>(d.opacity_logits[i]);
    for (int k = 0; k < 12; ++k) c.sh[i][k] = static_cast<float>(d.sh[i][k]);
  }
  return c;
}

}  // namespace skyfall::testing
