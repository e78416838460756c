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
#include "core/option_range.h"
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
  // Gaussians whose centre projects further than this fraction of the image
  // size beyond its edges are culled. Near the camera plane of a close,
  // oblique camera (an orbit view) a Gaussian far to the side projects with
  // a footprint larger than the image and veils all of it (3DGS clamps the
  // projection's Jacobian at 1.3 x the half field of view for the same reason).
  double guard_band = 0.3;
  double sigma_extent = 3.0;           // blend within this many standard deviations (Mahalanobis)
  int sh_degree = 1;                   // 0 or 1
  // Also render the median depth (not differentiable; for DSMs and depth maps).
  bool median_depth = false;
  Eigen::Vector3d background = Eigen::Vector3d::Zero();
  void Check() const;                  // throws Error("raster", field, ...)
};
template <class IO> void Visit(IO& io, RasterOptions& o) {
  io.NotAnOption(o.median_depth);  // an output choice of each caller
  io("tile_px", o.tile_px,
     "Side of the square screen tiles the Gaussians are binned into", range::In(4, 64));
  io("min_alpha", o.min_alpha,
     "Contributions with a smaller alpha are skipped", range::AtLeast(0));
  io("max_alpha", o.max_alpha,
     "Alpha is clamped to this, which keeps transmittance invertible", range::Inside(0, 1));
  io("min_transmittance", o.min_transmittance,
     "A pixel stops blending once its transmittance falls below this", range::FromBelow(0, 1));
  io("dilation_px2", o.dilation_px2,
     "Added to the diagonal of each projected 2D covariance (anti-aliasing)", range::AtLeast(0));
  io("near_m", o.near_m,
     "Gaussians closer than this to the camera plane are culled", range::Above(0));
  io("guard_band", o.guard_band,
     "Gaussians whose centre projects further than this fraction of the image size beyond its edges are culled",
     range::AtLeast(0));
  io("sigma_extent", o.sigma_extent,
     "A Gaussian blends the pixels within this many standard deviations (Mahalanobis)", range::Above(0));
  io("sh_degree", o.sh_degree,
     "Degree of the spherical-harmonics colours: 0 or 1", range::OneOf({0, 1}));
  io("background", o.background,
     "Colour behind the Gaussians: red, green, blue, each in [0, 1]", range::In(0, 1));
}

// A projected Gaussian: everything the blending loops read about it, packed
// into one cache line (in float), because they visit Gaussians in depth
// order, i.e. at random places in memory.
template <typename T>
struct alignas(64) ScreenGaussian {
  T u = 0, v = 0;                      // 2D mean [px]
  T conic_a = 0, conic_b = 0, conic_c = 0;
  T opacity = 0;
  T rgb[3] = {0, 0, 0};
  T depth = 0;                         // camera depth minus reference_depth [m]
  T log_alpha_cut = 0;                 // power below this gives alpha < min_alpha
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // bounding box of the blending ellipse [px] (half-open)
};

// What the forward pass keeps for the backward pass.
template <typename T>
struct RasterState {
  // Per Gaussian, after projection: half the longer side of the pixel box
  // (0 for a culled Gaussian).
  std::vector<ScreenGaussian<T>> screen;
  std::vector<int> radius_px;
  // Per tile: Gaussian indices sorted front to back, as ranges into `order`.
  std::vector<int> order;
  std::vector<int> tile_begin, tile_end;
  std::vector<std::uint8_t> entry_blended;  // per `order` entry: it blended at least one pixel
  // Per Gaussian: its positions in `order`, in tile order, as ranges into
  // `entries` (the backward pass sums its gradient over them).
  std::vector<int> entries_begin;
  std::vector<int> entries;
  // Per pixel: final transmittance and 1 + the tile-list position of the
  // last Gaussian blended (0 when none).
  std::vector<T> final_transmittance;
  std::vector<int> contributors;
  std::size_t blends = 0;  // Gaussian-pixel pairs composited (for throughput figures)
};

template <typename T>
struct RenderOutput {
  int width_px = 0;
  int height_px = 0;
  std::vector<T> rgb;       // 3 per pixel, row-major
  std::vector<T> alpha;     // accumulated opacity, 1 - final transmittance
  std::vector<T> depth;     // expected depth (weighted mean) minus reference_depth_m; 0 where alpha is 0
  // With RasterOptions::median_depth: the depth of the Gaussian at which the
  // accumulated opacity first reaches 0.5, minus reference_depth_m; NaN where
  // it never does. Unlike the expected depth it does not average a roof
  // edge with the ground below, nor a surface with a faint floater above.
  std::vector<T> median_depth;
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
