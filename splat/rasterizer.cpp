#include "splat/rasterizer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <numeric>

#include "core/error.h"
#include "core/format.h"
#include "core/simd.h"
#include "core/simd_target.h"

// The kernels, once per SIMD path (core/simd_target.h): the same source at 4
// lanes for the x86-64 baseline, 8 for AVX2 + FMA and 16 for AVX-512.

namespace skyfall {

namespace raster_baseline {
#define SKYFALL_RASTER_LANES 4
#include "splat/rasterizer_kernels.inc"
#undef SKYFALL_RASTER_LANES
}  // namespace raster_baseline

#if defined(__x86_64__)
SKYFALL_TARGET_BEGIN(SKYFALL_TARGET_AVX2)
namespace raster_avx2 {
#define SKYFALL_RASTER_LANES 8
#include "splat/rasterizer_kernels.inc"
#undef SKYFALL_RASTER_LANES
}  // namespace raster_avx2
SKYFALL_TARGET_END

SKYFALL_TARGET_BEGIN(SKYFALL_TARGET_AVX512)
namespace raster_avx512 {
#define SKYFALL_RASTER_LANES 16
#include "splat/rasterizer_kernels.inc"
#undef SKYFALL_RASTER_LANES
}  // namespace raster_avx512
SKYFALL_TARGET_END
#define SKYFALL_RASTER_PATHS(call)                           \
  switch (ActiveSimdPath()) {                                \
    case SimdPath::kAvx512:                                  \
      return raster_avx512::call;                            \
    case SimdPath::kAvx2:                                    \
      return raster_avx2::call;                              \
    case SimdPath::kBaseline:                                \
      break;                                                 \
  }                                                          \
  return raster_baseline::call
#else
#define SKYFALL_RASTER_PATHS(call) return raster_baseline::call
#endif

void RasterOptions::Check() const {
  auto need = [](bool ok, const char* field, double v) {
    if (!ok) throw Error("raster", field, FormatDouble(v) + " is out of range");
  };
  need(tile_px >= 4 && tile_px <= 64, "tile_px", tile_px);
  need(min_alpha >= 0 && min_alpha < max_alpha, "min_alpha", min_alpha);
  need(max_alpha > 0 && max_alpha < 1, "max_alpha", max_alpha);
  need(min_transmittance >= 0 && min_transmittance < 1, "min_transmittance", min_transmittance);
  need(dilation_px2 >= 0, "dilation_px2", dilation_px2);
  need(near_m > 0, "near_m", near_m);
  need(guard_band >= 0, "guard_band", guard_band);
  need(sigma_extent > 0, "sigma_extent", sigma_extent);
  need(sh_degree == 0 || sh_degree == 1, "sh_degree", sh_degree);
}

template <typename T>
RenderOutput<T> RenderGaussians(const GaussianCloudT<T>& cloud, const PinholeCamera& cam, const RasterOptions& o,
                                const std::vector<ColourAffine<T>>* colour_affine) {
  SKYFALL_RASTER_PATHS(RenderGaussiansImpl(cloud, cam, o, colour_affine));
}

template <typename T>
GaussianGradients<T> BackwardGaussians(const GaussianCloudT<T>& cloud, const PinholeCamera& cam, const RasterOptions& o,
                                       const RenderOutput<T>& fwd, const std::vector<T>& d_rgb,
                                       const std::vector<T>& d_alpha, const std::vector<T>& d_depth,
                                       const std::vector<ColourAffine<T>>* colour_affine) {
  SKYFALL_RASTER_PATHS(BackwardGaussiansImpl(cloud, cam, o, fwd, d_rgb, d_alpha, d_depth, colour_affine));
}

template RenderOutput<float> RenderGaussians(const GaussianCloudT<float>&, const PinholeCamera&, const RasterOptions&,
                                             const std::vector<ColourAffine<float>>*);
template RenderOutput<double> RenderGaussians(const GaussianCloudT<double>&, const PinholeCamera&, const RasterOptions&,
                                              const std::vector<ColourAffine<double>>*);
template GaussianGradients<float> BackwardGaussians(const GaussianCloudT<float>&, const PinholeCamera&,
                                                    const RasterOptions&, const RenderOutput<float>&,
                                                    const std::vector<float>&, const std::vector<float>&,
                                                    const std::vector<float>&,
                                                    const std::vector<ColourAffine<float>>*);
template GaussianGradients<double> BackwardGaussians(const GaussianCloudT<double>&, const PinholeCamera&,
                                                     const RasterOptions&, const RenderOutput<double>&,
                                                     const std::vector<double>&, const std::vector<double>&,
                                                     const std::vector<double>&,
                                                     const std::vector<ColourAffine<double>>*);

}  // namespace skyfall
