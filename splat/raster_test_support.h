// Shared by the splat tests that compare analytic gradients with central
// differences.
#pragma once

#include "splat/rasterizer.h"

namespace skyfall::testing {

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

}  // namespace skyfall::testing
