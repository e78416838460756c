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
#if defined(__x86_64__)
#include <immintrin.h>  // lanes_body.inc: one-instruction mask tests
#endif
#include <limits>
#include <memory>
#include <numeric>

#include "core/error.h"
#include "core/format.h"
#include "core/simd.h"
#include "core/simd_target.h"

namespace skyfall {
namespace {

// Sorts (depth, Gaussian index) pairs that arrive in index order by depth,
// ties by index (front to back, deterministic). Float depths take a stable
// least-significant-digit radix sort of their order-preserving bits: three
// passes of 11 bits, several times faster than a comparison sort at 100k
// Gaussians. Double depths (the finite-difference tests) take a plain sort.
void SortFrontToBack(std::vector<std::pair<float, int>>& v) {
  constexpr int kBits = 11, kBuckets = 1 << kBits;
  const std::size_t n = v.size();
  std::vector<std::uint32_t> key(n), key_tmp(n);
  for (std::size_t k = 0; k < n; ++k) {
    std::uint32_t u;
    std::memcpy(&u, &v[k].first, sizeof(u));
    key[k] = (u & 0x80000000u) ? ~u : (u | 0x80000000u);  // negative floats reversed, below positive ones
  }
  std::vector<std::pair<float, int>> tmp(n);
  for (int shift = 0; shift < 32; shift += kBits) {
    std::vector<std::size_t> start(kBuckets + 1, 0);
    for (std::size_t k = 0; k < n; ++k) ++start[((key[k] >> shift) & (kBuckets - 1)) + 1];
    std::partial_sum(start.begin(), start.end(), start.begin());
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t at = start[(key[k] >> shift) & (kBuckets - 1)]++;
      tmp[at] = v[k];
      key_tmp[at] = key[k];
    }
    v.swap(tmp);
    key.swap(key_tmp);
  }
}
void SortFrontToBack(std::vector<std::pair<double, int>>& v) { tbb::parallel_sort(v.begin(), v.end()); }

}  // namespace

// The kernels, once per SIMD path (core/simd_target.h): the same source at 4
// lanes for the x86-64 baseline, 8 for AVX2 + FMA and 16 for AVX-512.

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
#endif
#define SKYFALL_RASTER_PATHS(call) SKYFALL_RETURN_FOR_ACTIVE_PATH(raster, call)

void RasterOptions::Check() const {
  CheckOptionRanges(*this, "raster");
  if (!(min_alpha < max_alpha)) {
    throw Error("raster", "min_alpha", FormatDouble(min_alpha) + " must be below max_alpha " + FormatDouble(max_alpha));
  }
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
