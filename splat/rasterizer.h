// Differentiable tile-based rasterizer of 3D Gaussians (3DGS: EWA splatting,
// front-to-back alpha compositing) for pinhole cameras, with exact gradients.
//
// Satellite cameras are ~6e5 m away with focal lengths ~2e6 px: everything
// per Gaussian (camera transform, projection, 2D covariance and their
// gradients) runs in double; only the per-pixel blending runs in T (float for
// speed, double for finite-difference tests). Depths are blended relative to
// a per-camera reference depth so float keeps millimetres.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "core/gaussians.h"
#include "core/pinhole.h"
#include "splat/appearance.h"

namespace skyfall {

struct RasterOptions {
  int tile_px = 16;                    // square tile side [px]
  double min_alpha = 1.0 / 255.0;      // contributions below this are skipped
  double max_alpha = 0.99;             // clamp that keeps transmittance invertible
  double min_transmittance = 1e-4;     // early termination of a pixel
  double dilation_px2 = 0.3;           // added to the 2D covariance diagonal (anti-aliasing) [px^2]
  double near_m = 0.2;                 // Gaussians closer than this to the camera plane are culled [m]
  double sigma_extent = 3.0;           // screen radius in standard deviations
  int sh_degree = 1;                   // 0 or 1
  Eigen::Vector3d background = Eigen::Vector3d::Zero();
  void Check() const;                  // throws Error("raster", field, ...)
};

// What the forward pass keeps for the backward pass.
template <typename T>
struct RasterState {
  // Per Gaussian, after projection (invisible ones have radius 0).
  std::vector<T> u, v;                 // 2D mean [px]
  std::vector<T> conic_a, conic_b, conic_c;
  std::vector<T> opacity;
  std::vector<T> red, green, blue;
  std::vector<T> depth;                // camera depth minus reference_depth [m]
  std::vector<int> radius_px;
  std::vector<Eigen::Vector4i> footprint;  // pixel box x0, y0, x1, y1 (half-open) within the radius
  std::vector<T> log_alpha_cut;        // power below this gives alpha < min_alpha
  std::vector<std::uint8_t> colour_clamped;  // bit c set: channel c clamped at 0
  // Per tile: Gaussian indices sorted front to back, as ranges into `order`.
  std::vector<int> order;
  std::vector<int> tile_begin, tile_end;
  // Per pixel: final transmittance and 1 + the tile-list position of the
  // last Gaussian blended (0 when none).
  std::vector<T> final_transmittance;
  std::vector<int> contributors;
};

template <typename T>
struct RenderOutput {
  int width_px = 0;
  int height_px = 0;
  std::vector<T> rgb;       // 3 per pixel, row-major
  std::vector<T> alpha;     // accumulated opacity, 1 - final transmittance
  std::vector<T> depth;     // expected depth (weighted mean) minus reference_depth_m; 0 where alpha is 0
  double reference_depth_m = 0;  // camera depth of the frame origin
  RasterState<T> state;
};

// `colour_affine` (optional, one per Gaussian) transforms each Gaussian's SH
// colour before the clamp at 0: colour = gamma * colour + beta (appearance.h).
template <typename T>
RenderOutput<T> RenderGaussians(const GaussianCloudT<T>& cloud, const PinholeCamera& camera,
                                const RasterOptions& options,
                                const std::vector<ColourAffine<T>>* colour_affine = nullptr);

// Gradients of a scalar loss with respect to every Gaussian parameter.
template <typename T>
struct GaussianGradients {
  GaussianCloudT<T> d;                 // same layout as the cloud
  std::vector<T> mean2d_norm;          // |dL/d(u, v)| per Gaussian, for densification [1/px]
  std::vector<ColourAffine<T>> d_colour_affine;  // when rendered with a colour transform
};

// `d_rgb`, `d_alpha`, `d_depth`: dL/d of the matching RenderOutput fields
// (an empty vector means zero).
template <typename T>
GaussianGradients<T> BackwardGaussians(const GaussianCloudT<T>& cloud, const PinholeCamera& camera,
                                       const RasterOptions& options, const RenderOutput<T>& forward,
                                       const std::vector<T>& d_rgb, const std::vector<T>& d_alpha,
                                       const std::vector<T>& d_depth,
                                       const std::vector<ColourAffine<T>>* colour_affine = nullptr);

}  // namespace skyfall
