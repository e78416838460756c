#include "dense/dense.h"

#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numeric>

#include "core/error.h"
#include "core/simd.h"
#include "core/simd_target.h"
#include "core/stats.h"
#include "dense/hole_fill.h"

namespace skyfall {

// The sweep's inner loops once per SIMD path (core/simd_target.h).
namespace dense_baseline {
#include "dense/dense_kernels.inc"
}  // namespace dense_baseline
#if defined(__x86_64__)
SKYFALL_TARGET_BEGIN(SKYFALL_TARGET_AVX2)
namespace dense_avx2 {
#include "dense/dense_kernels.inc"
}  // namespace dense_avx2
SKYFALL_TARGET_END
SKYFALL_TARGET_BEGIN(SKYFALL_TARGET_AVX512)
namespace dense_avx512 {
#include "dense/dense_kernels.inc"
}  // namespace dense_avx512
SKYFALL_TARGET_END
#endif

void DenseOptions::Check() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) throw Error("dense", name, "must be a finite value > 0, got " + std::to_string(v));
  };
  if (cell_m != 0) positive(cell_m, "cell_m");  // 0: automatic
  positive(height_step_m, "height_step_m");
  positive(cost_truncation, "cost_truncation");
  positive(min_std, "min_std");
  positive(max_cost, "max_cost");
  positive(max_median_deviation_m, "max_median_deviation_m");
  positive(fill_radius_m, "fill_radius_m");
  if (!(fill_roof_rim_fraction >= 0 && fill_roof_rim_fraction <= 1))
    throw Error("dense", "fill_roof_rim_fraction", "must be in [0, 1] (0 = off), got " + std::to_string(fill_roof_rim_fraction));
  if (!(max_fill_reach_m >= fill_radius_m)) throw Error("dense", "max_fill_reach_m", "must be >= fill_radius_m");
  positive(fill_ground_radius_m, "fill_ground_radius_m");
  if (!(fill_ground_tolerance_m >= 0)) throw Error("dense", "fill_ground_tolerance_m", "must be >= 0");
  if (!(fill_ground_max_rise_m >= 0)) throw Error("dense", "fill_ground_max_rise_m", "must be >= 0 (0 = off)");
  if (!(floating_patch_max_m2 >= 0)) throw Error("dense", "floating_patch_max_m2", "must be >= 0 (0 = off)");
  if (!(floating_patch_min_rise_m >= 0)) throw Error("dense", "floating_patch_min_rise_m", "must be >= 0");
  if (!(visibility_prior_pairs >= 0)) throw Error("dense", "visibility_prior_pairs", "must be >= 0");
  if (visibility_near_cells < -1)
    throw Error("dense", "visibility_near_cells", "must be >= 0, or -1 (the window's radius), got " + std::to_string(visibility_near_cells));
  if (!(visibility_tolerance_m >= 0)) throw Error("dense", "visibility_tolerance_m", "must be >= 0");
  if (!(height_margin_m >= 0)) throw Error("dense", "height_margin_m", "must be >= 0");
  if (!(height_percentile >= 0 && height_percentile < 0.5)) throw Error("dense", "height_percentile", "must be in [0, 0.5)");
  positive(step_min_m, "step_min_m");
  positive(support_grey_sigma, "support_grey_sigma");
  if (!(step_cost_margin >= 0)) throw Error("dense", "step_cost_margin", "must be >= 0, got " + std::to_string(step_cost_margin));
  if (step_reach_cells < 1) throw Error("dense", "step_reach_cells", "must be >= 1, got " + std::to_string(step_reach_cells));
  if (support_radius_cells < 1)
    throw Error("dense", "support_radius_cells", "must be >= 1, got " + std::to_string(support_radius_cells));
  if (coarse_factor < 1) throw Error("dense", "coarse_factor", "must be >= 1 (1 = off), got " + std::to_string(coarse_factor));
  if (max_heights < 2) throw Error("dense", "max_heights", "must be >= 2");
  if (window_cells < 3 || window_cells % 2 == 0) throw Error("dense", "window_cells", "must be odd and >= 3");
  if (coarse_window_cells < 3 || coarse_window_cells % 2 == 0)
    throw Error("dense", "coarse_window_cells", "must be odd and >= 3");
  if (max_pairs < 1) throw Error("dense", "max_pairs", "must be >= 1");
  if (!(min_pair_angle_deg >= 0 && max_pair_angle_deg > min_pair_angle_deg))
    throw Error("dense", "max_pair_angle_deg", "must exceed min_pair_angle_deg >= 0");
  if (!(sgm_p1 >= 0 && sgm_p2 >= sgm_p1)) throw Error("dense", "sgm_p2", "must be >= sgm_p1 >= 0");
}

namespace {

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();

// Grey level of a view scaled so that its 99th percentile is 1: NCC ignores
// the scale, but min_std is then the same threshold for every sensor range.
struct GreyImage {
  int width = 0, height = 0;
  std::vector<float> values;
};

GreyImage ToGrey(const DenseView& v) {
  GreyImage g;
  g.width = v.width_px;
  g.height = v.height_px;
  const std::size_t n = static_cast<std::size_t>(g.width) * g.height;
  g.values.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    float sum = 0;
    for (int b = 0; b < v.bands; ++b) sum += v.pixels[k * v.bands + b];
    g.values[k] = sum / static_cast<float>(v.bands);
  }
  std::vector<float> finite;
  finite.reserve(n);
  for (float x : g.values)
    if (std::isfinite(x)) finite.push_back(x);
  const float p99 = Quantile(std::move(finite), 0.99);
  const float scale = p99 > 0 ? 1.0f / p99 : 1.0f;
  for (float& x : g.values) x *= scale;
  return g;
}

using Projection = Eigen::Matrix<double, 3, 4>;

Projection ProjectionOf(const PinholeCamera& c) {
  Projection rt;
  rt.leftCols<3>() = c.cam_from_world_rotation;
  rt.col(3) = c.cam_from_world_translation;
  return c.K() * rt;
}

// The kernels of the active SIMD path.
struct DenseKernels {
  decltype(&dense_baseline::WindowStatsKernel) window_stats;
  decltype(&dense_baseline::PairCostRows<false>) pair_cost;
  decltype(&dense_baseline::PairCostRows<true>) pair_cost_masked;
  decltype(&dense_baseline::WarpRow) warp_row;
  decltype(&dense_baseline::SgmStep) sgm_step;
};
#define SKYFALL_DENSE_KERNELS(ns)                                                                 \
  DenseKernels {                                                                                  \
    &ns::WindowStatsKernel, &ns::PairCostRows<false>, &ns::PairCostRows<true>, &ns::WarpRow, &ns::SgmStep \
  }

const DenseKernels& ActiveKernels() {
  static const DenseKernels baseline = SKYFALL_DENSE_KERNELS(dense_baseline);
#if defined(__x86_64__)
  static const DenseKernels avx2 = SKYFALL_DENSE_KERNELS(dense_avx2);
  static const DenseKernels avx512 = SKYFALL_DENSE_KERNELS(dense_avx512);
  return ForActivePath(baseline, avx2, avx512);
#else
  return baseline;
#endif
}
#undef SKYFALL_DENSE_KERNELS

// The image sampled (bilinearly) at the grid cells of rows [row_begin,
// row_end) lifted to height h, into `out` (those rows only); NaN where a
// cell projects outside the image. `scratch` is resized as needed.
void WarpToGrid(const DenseKernels& kernels, const GreyImage& image, const Projection& P, const HeightGrid& grid,
                double height_m, int row_begin, int row_end, float* out, std::vector<float>& scratch) {
  // The projection is linear in x along a row: start and step.
  const Eigen::Vector3d step = P.col(0) * grid.cell_m;
  scratch.resize(3 * static_cast<std::size_t>(grid.nx));
  for (int j = row_begin; j < row_end; ++j) {
    const Eigen::Vector3d start = P * Eigen::Vector4d(grid.x0_m, grid.y0_m + j * grid.cell_m, height_m, 1.0);
    kernels.warp_row(image.values.data(), image.width, image.height, start.data(), step.data(), grid.nx,
                     out + static_cast<std::size_t>(j - row_begin) * grid.nx, scratch.data());
  }
}

// Window statistics of one warped image at one height, computed once and
// shared by every pair the image is in (WindowStatsKernel).
struct WindowStats {
  std::vector<float> values, mean, inv_std;
};

// One SGM direction (dx, dy) added into `total`. Cells along a row are
// independent when dy != 0 (their predecessors are in the previous row), and
// rows are independent when dy == 0, so both parallelize without changing
// the result.
void AddSgmDirection(const DenseKernels& kernels, const std::vector<float>& cost, int nx, int ny, int nh, float p1,
                     float p2, int dx, int dy, std::vector<float>& total) {
  const std::size_t row_len = static_cast<std::size_t>(nx) * nh;
  if (dy == 0) {
    tbb::parallel_for(0, ny, [&](int j) {
      std::vector<float> a(nh), b(nh);
      const int i0 = dx > 0 ? 0 : nx - 1;
      for (int s = 0; s < nx; ++s) {
        const int i = i0 + s * dx;
        const std::size_t cell = static_cast<std::size_t>(j) * nx + i;
        const float* c = cost.data() + cell * nh;
        if (s == 0) std::copy(c, c + nh, b.data());
        else kernels.sgm_step(a.data(), c, b.data(), nh, p1, p2);
        float* t = total.data() + cell * nh;
        for (int d = 0; d < nh; ++d) t[d] += b[d];
        std::swap(a, b);
      }
    });
    return;
  }
  std::vector<float> prev(row_len), cur(row_len);
  const int j0 = dy > 0 ? 0 : ny - 1;
  for (int s = 0; s < ny; ++s) {
    const int j = j0 + s * dy;
    tbb::parallel_for(0, nx, [&](int i) {
      const std::size_t cell = static_cast<std::size_t>(j) * nx + i;
      const float* c = cost.data() + cell * nh;
      float* out = cur.data() + static_cast<std::size_t>(i) * nh;
      const int pi = i - dx;
      if (s == 0 || pi < 0 || pi >= nx) std::copy(c, c + nh, out);
      else kernels.sgm_step(prev.data() + static_cast<std::size_t>(pi) * nh, c, out, nh, p1, p2);
      float* t = total.data() + cell * nh;
      for (int d = 0; d < nh; ++d) t[d] += out[d];
    });
    std::swap(prev, cur);
  }
}

float Median3x3(const std::vector<float>& h, int nx, int ny, int i, int j) {
  float v[9];
  int n = 0;
  for (int b = std::max(0, j - 1); b <= std::min(ny - 1, j + 1); ++b)
    for (int a = std::max(0, i - 1); a <= std::min(nx - 1, i + 1); ++a) {
      const float x = h[static_cast<std::size_t>(b) * nx + a];
      if (std::isfinite(x)) v[n++] = x;
    }
  if (n == 0) return kNan;
  std::nth_element(v, v + n / 2, v + n);
  return v[n / 2];
}

// What the sweeps of one run share: the grid, the heights and the views.
struct Sweep {
  const DenseOptions& o;
  const HeightGrid& grid;  // geometry only
  double z_lo = 0;
  double step_m = 0;  // height_step_m, or coarser where the range needs more than max_heights
  int nh = 0;
  const std::vector<DensePair>& pairs;
  const std::vector<int>& slot;  // view index -> index into grey / projection
  const std::vector<GreyImage>& grey;
  const std::vector<Projection>& projection;
  std::size_t Cells() const { return static_cast<std::size_t>(grid.nx) * grid.ny; }
  double Height(int d) const { return z_lo + d * step_m; }
};

// Rows of the grid swept together: every view's warp and window statistics
// and every pair's cost for a strip of this many rows (plus the window's
// halo) stay in the cache, where a whole grid of 19 views would not.
constexpr int kStripRows = 16;

// What one thread of the sweep reuses from height to height, sized for one
// strip of rows with its halo.
struct SweepScratch {
  std::vector<float> warped, warp_scratch, scratch, ring, sum, count, block;
  std::vector<WindowStats> stats;
  std::vector<std::vector<float>> visible;
  void Resize(std::size_t strip_cells, std::size_t cells, std::size_t views, int nx, int r, int heights_per_block,
              bool masked) {
    if (!warped.empty()) return;
    warped.resize(strip_cells);
    scratch.resize(dense_baseline::WindowStatsScratch(nx, r));
    ring.resize(static_cast<std::size_t>(2 * r + 3) * nx);
    sum.resize(strip_cells);
    block.resize(cells * heights_per_block);
    stats.resize(views);
    for (WindowStats& w : stats) {
      w.values.resize(strip_cells);
      w.mean.resize(strip_cells);
      w.inv_std.resize(strip_cells);
    }
    if (masked) {
      count.resize(strip_cells);
      visible.assign(views, std::vector<float>(strip_cells));
    }
  }
};

// The cost volume, cell-major so SGM reads each cell's heights
// contiguously: per cell and height, the mean truncated pair cost. With
// `seen_above` (per view slot and cell, the height above which the view
// sees the cell), a pair counts only where both its views see the point,
// and a point no pair sees costs the truncation. Heights are swept in
// blocks, each written to the volume as a run of heights per cell; each
// height in strips of rows (kStripRows).
std::vector<float> CostVolume(const Sweep& s, const std::vector<std::vector<float>>* seen_above,
                              const std::string& label, Progress& progress) {
  const HeightGrid& g = s.grid;
  const DenseKernels& kernels = ActiveKernels();
  const std::size_t cells = s.Cells();
  const std::size_t views = s.grey.size();
  const int nh = s.nh;
  const int r = s.o.window_cells / 2;
  const int block_heights = std::clamp(nh / 16, 1, 8);
  const int blocks = (nh + block_heights - 1) / block_heights;
  const std::size_t strip_cells = static_cast<std::size_t>(kStripRows + 2 * r) * g.nx;
  std::vector<float> cost(cells * nh);
  progress.Begin(label, nh);
  std::atomic<int> done{0};
  const float trunc = static_cast<float>(s.o.cost_truncation);
  const float min_var = static_cast<float>(s.o.min_std * s.o.min_std);
  const float prior = static_cast<float>(s.o.visibility_prior_pairs);
  const float inv_pairs = 1.0f / static_cast<float>(s.pairs.size());
  tbb::enumerable_thread_specific<SweepScratch> scratch;
  tbb::parallel_for(0, blocks, [&](int block) {
    SweepScratch& t = scratch.local();
    t.Resize(strip_cells, cells, views, g.nx, r, block_heights, seen_above != nullptr);
    const int d0 = block * block_heights, d1 = std::min(nh, d0 + block_heights);
    for (int d = d0; d < d1; ++d) {
      const double height = s.Height(d);
      float* out = t.block.data() + static_cast<std::size_t>(d - d0) * cells;
      for (int j0 = 0; j0 < g.ny; j0 += kStripRows) {
        // The strip's rows [j0, j1) and the rows their windows reach,
        // [s0, s1), swept as a grid of their own: its first and last r rows
        // are border there, but those are the neighbouring strips' rows
        // (or the grid's own border), and only [j0, j1) is kept.
        const int j1 = std::min(g.ny, j0 + kStripRows);
        const int s0 = std::max(0, j0 - r), s1 = std::min(g.ny, j1 + r);
        const int rows = s1 - s0;
        const std::size_t first = static_cast<std::size_t>(s0) * g.nx;
        const std::size_t n = static_cast<std::size_t>(rows) * g.nx;
        for (std::size_t v = 0; v < views; ++v) {
          WarpToGrid(kernels, s.grey[v], s.projection[v], g, height, s0, s1, t.warped.data(), t.warp_scratch);
          kernels.window_stats(t.warped.data(), g.nx, rows, r, min_var, t.stats[v].values.data(),
                               t.stats[v].mean.data(), t.stats[v].inv_std.data(), t.scratch.data());
        }
        std::fill(t.sum.begin(), t.sum.begin() + n, 0.0f);
        if (seen_above) {
          for (std::size_t v = 0; v < views; ++v) {
            const float* seen = (*seen_above)[v].data() + first;
            for (std::size_t k = 0; k < n; ++k) t.visible[v][k] = height >= seen[k] ? 1.0f : 0.0f;
          }
          std::fill(t.count.begin(), t.count.begin() + n, 0.0f);
        }
        for (const DensePair& p : s.pairs) {
          const int ia = s.slot[p.a], ib = s.slot[p.b];
          const WindowStats& a = t.stats[ia];
          const WindowStats& b = t.stats[ib];
          if (seen_above)
            kernels.pair_cost_masked(a.values.data(), b.values.data(), a.mean.data(), b.mean.data(), a.inv_std.data(),
                                     b.inv_std.data(), t.visible[ia].data(), t.visible[ib].data(), g.nx, rows, r,
                                     trunc, t.sum.data(), t.count.data(), t.ring.data());
          else
            kernels.pair_cost(a.values.data(), b.values.data(), a.mean.data(), b.mean.data(), a.inv_std.data(),
                              b.inv_std.data(), nullptr, nullptr, g.nx, rows, r, trunc, t.sum.data(), nullptr,
                              t.ring.data());
        }
        const std::size_t keep = static_cast<std::size_t>(j0 - s0) * g.nx;
        const std::size_t keep_n = static_cast<std::size_t>(j1 - j0) * g.nx;
        float* dst = out + static_cast<std::size_t>(j0) * g.nx;
        for (std::size_t k = 0; k < keep_n; ++k) {
          if (!seen_above) {
            dst[k] = t.sum[keep + k] * inv_pairs;
          } else {
            const float m = t.count[keep + k] + prior;
            dst[k] = m > 0 ? (t.sum[keep + k] + prior * trunc) / m : trunc;
          }
        }
      }
      progress.Advance(++done, "");
    }
    for (std::size_t k = 0; k < cells; ++k)
      for (int d = d0; d < d1; ++d) cost[k * nh + d] = t.block[static_cast<std::size_t>(d - d0) * cells + k];
  });
  progress.End();
  return cost;
}

// Heights chosen from a cost volume: SGM, the best height per cell refined
// by a parabola through its neighbours, cells matching worse than max_cost
// and speckles (far from their 3x3 median) left NaN.
struct CellHeights {
  std::vector<float> height_m, cost;
  std::size_t low_cost = 0, speckles = 0;
};

CellHeights PickHeights(const Sweep& s, const std::vector<float>& cost, Progress& progress) {
  const HeightGrid& g = s.grid;
  const DenseOptions& o = s.o;
  const std::size_t cells = s.Cells();
  const int nh = s.nh;
  progress.Begin("dense: semi-global matching", 0);
  const std::vector<float> total =
      AggregateSgm(cost, g.nx, g.ny, nh, static_cast<float>(o.sgm_p1), static_cast<float>(o.sgm_p2));
  progress.End();
  CellHeights out;
  out.height_m.assign(cells, kNan);
  out.cost.assign(cells, static_cast<float>(o.cost_truncation));
  for (std::size_t k = 0; k < cells; ++k) {
    const float* t = total.data() + k * nh;
    const int best = static_cast<int>(std::min_element(t, t + nh) - t);
    out.cost[k] = cost[k * nh + best];
    if (out.cost[k] > o.max_cost) continue;
    ++out.low_cost;
    double offset = 0;
    if (best > 0 && best + 1 < nh) {
      const double curvature = t[best - 1] - 2.0 * t[best] + t[best + 1];
      if (curvature > 0) offset = std::clamp(0.5 * (t[best - 1] - t[best + 1]) / curvature, -0.5, 0.5);
    }
    out.height_m[k] = static_cast<float>(s.z_lo + (best + offset) * s.step_m);
  }
  std::vector<float> filtered = out.height_m;
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = g.Index(i, j);
      if (!std::isfinite(out.height_m[k])) continue;
      if (std::abs(out.height_m[k] - Median3x3(out.height_m, g.nx, g.ny, i, j)) > o.max_median_deviation_m) {
        filtered[k] = kNan;
        ++out.speckles;
      }
    }
  out.height_m = std::move(filtered);
  return out;
}

// `image` blurred with a Gaussian of `sigma_px`, as a normalized
// convolution: pixels without data (NaN) neither darken nor brighten their
// neighbours, and a pixel whose blur is mostly no data stays NaN.
GreyImage Blurred(const GreyImage& image, double sigma_px) {
  cv::Mat values(image.height, image.width, CV_32F), weight(image.height, image.width, CV_32F);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const float v = image.values[static_cast<std::size_t>(y) * image.width + x];
      const bool ok = std::isfinite(v);
      values.at<float>(y, x) = ok ? v : 0.0f;
      weight.at<float>(y, x) = ok ? 1.0f : 0.0f;
    }
  cv::GaussianBlur(values, values, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REPLICATE);
  cv::GaussianBlur(weight, weight, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REPLICATE);
  GreyImage out = image;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const float w = weight.at<float>(y, x);
      out.values[static_cast<std::size_t>(y) * image.width + x] = w > 0.5f ? values.at<float>(y, x) / w : kNan;
    }
  return out;
}

// Image pixels per metre of ground at `centre_enu_m` (the mean over east
// and north): what a ground distance spans in the view.
double PixelsPerMetre(const Projection& P, const Eigen::Vector3d& centre_enu_m) {
  auto pixel = [&](const Eigen::Vector3d& w) {
    const Eigen::Vector3d h = P * w.homogeneous();
    return Eigen::Vector2d(h.head<2>() / h.z());
  };
  const Eigen::Vector2d c = pixel(centre_enu_m);
  return 0.5 * ((pixel(centre_enu_m + Eigen::Vector3d::UnitX()) - c).norm() +
                (pixel(centre_enu_m + Eigen::Vector3d::UnitY()) - c).norm());
}

// Heights for the cells of the fine sweep's grid from a sweep at
// coarse_factor times its cell (DenseOptions::coarse_factor), on the views
// blurred to that cell (a Gaussian of half a coarse cell, against
// aliasing), interpolated bilinearly between coarse cells (the nearest
// where a neighbour has no height); NaN where the coarse sweep has none.
std::vector<float> CoarseSweepHeights(const Sweep& fine, const Eigen::Vector3d& centre_enu_m, Progress& progress) {
  const HeightGrid& g = fine.grid;
  const int f = fine.o.coarse_factor;
  std::vector<float> out(fine.Cells(), kNan);
  HeightGrid c;
  c.cell_m = g.cell_m * f;
  c.x0_m = g.x0_m + 0.5 * (f - 1) * g.cell_m;  // a coarse cell is centred on its f x f fine cells
  c.y0_m = g.y0_m + 0.5 * (f - 1) * g.cell_m;
  c.nx = g.nx / f;
  c.ny = g.ny / f;
  DenseOptions coarse_options = fine.o;
  coarse_options.window_cells = fine.o.coarse_window_cells;
  if (c.nx <= coarse_options.window_cells || c.ny <= coarse_options.window_cells) return out;
  std::vector<GreyImage> blurred(fine.grey.size());
  tbb::parallel_for(0, static_cast<int>(fine.grey.size()), [&](int v) {
    blurred[v] = Blurred(fine.grey[v], 0.5 * c.cell_m * PixelsPerMetre(fine.projection[v], centre_enu_m));
  });
  const Sweep coarse{coarse_options, c, fine.z_lo, fine.step_m, fine.nh, fine.pairs, fine.slot, blurred, fine.projection};
  const std::vector<float> cost = CostVolume(coarse, nullptr, "dense: sweeping holes at a coarser scale", progress);
  const std::vector<float> picked = PickHeights(coarse, cost, progress).height_m;
  // Wide windows fatten what they straddle: at a roof's edge the roof's
  // texture wins, and a band of ground takes the roof's height. Only coarse
  // cells whose neighbours within kSmoothReach cells are measured and lie
  // within kSmoothSlope of them keep a height: inside a roof, gabled or
  // flat, or on open ground, not near a step.
  constexpr int kSmoothReach = 2;
  constexpr float kSmoothSlope = 1.0f;  // [m per coarse cell]; a roof of 30 deg rises 0.9 m per 1.5 m cell
  std::vector<float> h(picked.size(), kNan);
  for (int b = 0; b < c.ny; ++b)
    for (int a = 0; a < c.nx; ++a) {
      const float centre = picked[c.Index(a, b)];
      bool smooth = std::isfinite(centre);
      for (int db = -kSmoothReach; db <= kSmoothReach && smooth; ++db)
        for (int da = -kSmoothReach; da <= kSmoothReach && smooth; ++da) {
          const int x = a + da, y = b + db;
          if (x < 0 || y < 0 || x >= c.nx || y >= c.ny) continue;
          const float n = picked[c.Index(x, y)];
          smooth = std::isfinite(n) && std::abs(n - centre) <= kSmoothSlope * std::max(std::abs(da), std::abs(db));
        }
      if (smooth) h[c.Index(a, b)] = centre;
    }
  auto at = [&](int a, int b) { return h[c.Index(std::clamp(a, 0, c.nx - 1), std::clamp(b, 0, c.ny - 1))]; };
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const double u = (i - 0.5 * (f - 1)) / f, v = (j - 0.5 * (f - 1)) / f;  // coarse cell coordinates
      const int a = static_cast<int>(std::floor(u)), b = static_cast<int>(std::floor(v));
      const float tu = static_cast<float>(u - a), tv = static_cast<float>(v - b);
      const float h00 = at(a, b), h10 = at(a + 1, b), h01 = at(a, b + 1), h11 = at(a + 1, b + 1);
      float value = (1 - tv) * ((1 - tu) * h00 + tu * h10) + tv * ((1 - tu) * h01 + tu * h11);
      if (!std::isfinite(value))
        value = at(static_cast<int>(std::lround(u)), static_cast<int>(std::lround(v)));
      out[g.Index(i, j)] = value;
    }
  return out;
}

// Per view (ENU directions toward the cameras), the height above which each
// cell of `surface_m` is seen (VisibleAbove, past `near_cells`), less
// `tolerance_m`: what the visibility pass and the step decision count as seen.
std::vector<std::vector<float>> SeenAbove(const HeightGrid& g, const std::vector<float>& surface_m,
                                          const std::vector<Eigen::Vector3d>& to_cameras, double floor_m,
                                          double tolerance_m, int near_cells) {
  std::vector<std::vector<float>> seen_above(to_cameras.size());
  tbb::parallel_for(0, static_cast<int>(to_cameras.size()), [&](int v) {
    seen_above[v] = VisibleAbove(g, surface_m, to_cameras[v], floor_m, near_cells);
    for (float& h : seen_above[v]) h -= static_cast<float>(tolerance_m);
  });
  return seen_above;
}

// One candidate height of one cell scored with adaptive support weights:
// every view that sees the point (all views without `seen_above`) is
// sampled on the (2R+1)^2 window of cells lifted to `height_m`; each window
// cell weighs exp(-|grey - centre grey| / sigma - distance / R) in the first
// view of `nadir_first` that sees it with the whole window inside the
// image; each pair scores 1 - weighted NCC (truncated, the truncation where
// a window is too plain), averaged as the masked sweep does. NaN when no
// view can serve as the reference.
struct SupportScratch {
  std::vector<float> samples, weights, weighted, mean, inv_std;
  std::vector<std::uint8_t> usable;
};

float SupportWeightedCost(const Sweep& s, const std::vector<std::vector<float>>* seen_above,
                          const std::vector<int>& nadir_first, int i, int j, double height_m, SupportScratch& t) {
  const HeightGrid& g = s.grid;
  const int r = s.o.support_radius_cells, w = 2 * r + 1, n = w * w;
  const std::size_t views = s.grey.size();
  const std::size_t centre_cell = g.Index(i, j);
  t.samples.resize(views * n);
  t.weights.resize(n);
  t.usable.assign(views, 0);
  for (std::size_t v = 0; v < views; ++v) {
    if (seen_above && height_m < (*seen_above)[v][centre_cell]) continue;
    const GreyImage& image = s.grey[v];
    float* out = t.samples.data() + v * n;
    bool inside = true;
    for (int b = -r; b <= r && inside; ++b)
      for (int a = -r; a <= r && inside; ++a) {
        const Eigen::Vector3d h = s.projection[v] * Eigen::Vector4d(g.x0_m + (i + a) * g.cell_m,
                                                                    g.y0_m + (j + b) * g.cell_m, height_m, 1.0);
        const double x = h.x() / h.z(), y = h.y() / h.z();
        const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
        if (!(h.z() > 0) || x0 < 0 || y0 < 0 || x0 + 1 >= image.width || y0 + 1 >= image.height) {
          inside = false;
          break;
        }
        const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
        const float* p = image.values.data() + static_cast<std::size_t>(y0) * image.width + x0;
        const float top = p[0] + fx * (p[1] - p[0]);
        const float bottom = p[image.width] + fx * (p[image.width + 1] - p[image.width]);
        const float value = top + fy * (bottom - top);
        inside = std::isfinite(value);
        out[(b + r) * w + (a + r)] = value;
      }
    t.usable[v] = inside ? 1 : 0;
  }
  const auto reference = std::find_if(nadir_first.begin(), nadir_first.end(), [&](int v) { return t.usable[v]; });
  if (reference == nadir_first.end()) return kNan;
  const float* ref = t.samples.data() + static_cast<std::size_t>(*reference) * n;
  const float centre = ref[r * w + r];
  const float inv_sigma = static_cast<float>(1.0 / s.o.support_grey_sigma);
  for (int b = -r; b <= r; ++b)
    for (int a = -r; a <= r; ++a) {
      const int q = (b + r) * w + (a + r);
      const float distance = std::sqrt(static_cast<float>(a * a + b * b)) / static_cast<float>(r);
      t.weights[q] = std::exp(-std::abs(ref[q] - centre) * inv_sigma - distance);
    }
  float weight_sum = 0;
  for (int q = 0; q < n; ++q) weight_sum += t.weights[q];
  const float inv_weight = 1.0f / weight_sum;
  const float trunc = static_cast<float>(s.o.cost_truncation);
  const float min_var = static_cast<float>(s.o.min_std * s.o.min_std);
  // Per view: its weighted samples (w x) and weighted mean and variance;
  // per pair only the weighted product remains.
  t.weighted.resize(views * n);
  t.mean.assign(views, 0.0f);
  t.inv_std.assign(views, 0.0f);  // 0: too plain to correlate
  for (std::size_t v = 0; v < views; ++v) {
    if (!t.usable[v]) continue;
    const float* x = t.samples.data() + v * n;
    float* wx = t.weighted.data() + v * n;
    float sx = 0, sxx = 0;
    for (int q = 0; q < n; ++q) {
      wx[q] = t.weights[q] * x[q];
      sx += wx[q];
      sxx += wx[q] * x[q];
    }
    const float mean = sx * inv_weight, var = sxx * inv_weight - mean * mean;
    t.mean[v] = mean;
    if (var > min_var) t.inv_std[v] = 1.0f / std::sqrt(var);
  }
  float sum = 0, count = 0;
  for (const DensePair& p : s.pairs) {
    const int va = s.slot[p.a], vb = s.slot[p.b];
    if (!t.usable[va] || !t.usable[vb]) continue;
    count += 1;
    if (t.inv_std[va] == 0 || t.inv_std[vb] == 0) {
      sum += trunc;
      continue;
    }
    const float* wx = t.weighted.data() + static_cast<std::size_t>(va) * n;
    const float* y = t.samples.data() + static_cast<std::size_t>(vb) * n;
    float sxy = 0;
    for (int q = 0; q < n; ++q) sxy += wx[q] * y[q];
    const float covariance = sxy * inv_weight - t.mean[va] * t.mean[vb];
    sum += std::min(trunc, 1.0f - covariance * t.inv_std[va] * t.inv_std[vb]);
  }
  const float prior = seen_above ? static_cast<float>(s.o.visibility_prior_pairs) : 0.0f;
  return count + prior > 0 ? (sum + prior * trunc) / (count + prior) : trunc;
}

// The view slots ordered most nadir first: the reference view of
// SupportWeightedCost's weights.
std::vector<int> NadirFirst(const std::vector<DenseView>& views, const std::vector<int>& used_views,
                            const Eigen::Vector3d& centre) {
  std::vector<int> order(used_views.size());
  std::iota(order.begin(), order.end(), 0);
  auto up = [&](int k) { return (views[used_views[k]].camera.Centre() - centre).normalized().z(); };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return up(a) > up(b); });
  return order;
}

// DenseOptions::decide_filled_sides: each filled cell (`candidates`) is
// scored (SupportWeightedCost) at the ground (`terrain_m`) and at a raised
// height: its fill where that stands more than step_min_m above the
// ground, else the lowest measured height raised that much within
// `reach_cells` (then 4 x reach_cells) of it. The cell takes the other side
// where that side's cost is at most max_cost and step_cost_margin below its
// fill's, and where a cell filled at the ground has no measured ground
// within step_reach_cells: there the roof's side wins by the windows'
// fattening, as beside any step. A side no view can score decides nothing.
// Views count where they see the point past the measured surface
// (`measured_m`; holes hide nothing), near cells excepted as in the
// visibility pass. Returns how many cells changed side.
std::size_t DecideFilledSides(const Sweep& s, const std::vector<Eigen::Vector3d>& to_cameras,
                              const std::vector<int>& nadir_first, const std::vector<float>& measured_m,
                              const std::vector<float>& terrain_m, const std::vector<std::uint8_t>& candidates,
                              int reach_cells, std::vector<float>& height_m, Progress& progress) {
  const HeightGrid& g = s.grid;
  const float step_min = static_cast<float>(s.o.step_min_m);
  const float max_cost = static_cast<float>(s.o.max_cost), margin = static_cast<float>(s.o.step_cost_margin);
  // The measured heights raised above the ground, and their lowest within
  // the two reaches (the fill's first and largest, 5 and 20 m by default).
  std::vector<float> raised(measured_m.size(), kNan);
  for (std::size_t k = 0; k < raised.size(); ++k)
    if (measured_m[k] > terrain_m[k] + step_min) raised[k] = measured_m[k];
  const std::vector<float> raised_near = MinFilter(raised, g.nx, g.ny, reach_cells, WindowEdge::kClip);
  const std::vector<float> raised_far = MinFilter(raised, g.nx, g.ny, 4 * reach_cells, WindowEdge::kClip);
  // Measured ground within the step's reach: beside it a roof hypothesis
  // is the windows' fattening again.
  std::vector<float> ground_cells(measured_m.size(), kNan);
  for (std::size_t k = 0; k < ground_cells.size(); ++k)
    if (std::abs(measured_m[k] - terrain_m[k]) <= step_min) ground_cells[k] = 0.0f;
  const std::vector<float> ground_near =
      MinFilter(ground_cells, g.nx, g.ny, s.o.step_reach_cells, WindowEdge::kClip);
  const std::vector<std::vector<float>> seen_above =
      SeenAbove(g, measured_m, to_cameras, s.z_lo, s.o.visibility_tolerance_m,
                s.o.visibility_near_cells >= 0 ? s.o.visibility_near_cells : s.o.window_cells / 2);
  progress.Begin("dense: deciding filled cells between ground and roof", g.ny);
  std::atomic<int> rows_done{0};
  std::atomic<std::size_t> changed{0};
  tbb::enumerable_thread_specific<SupportScratch> scratch;
  const std::vector<float> before = height_m;
  tbb::parallel_for(0, g.ny, [&](int j) {
    SupportScratch& t = scratch.local();
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = g.Index(i, j);
      if (!candidates[k] || !std::isfinite(terrain_m[k]) || !std::isfinite(before[k])) continue;
      const bool filled_raised = before[k] > terrain_m[k] + step_min;
      if (!filled_raised && std::isfinite(ground_near[k])) continue;
      const float ground = terrain_m[k];
      const float roof = filled_raised ? before[k] : std::isfinite(raised_near[k]) ? raised_near[k] : raised_far[k];
      if (!std::isfinite(roof)) continue;
      const float cost_ground = SupportWeightedCost(s, &seen_above, nadir_first, i, j, ground, t);
      const float cost_roof = SupportWeightedCost(s, &seen_above, nadir_first, i, j, roof, t);
      if (!std::isfinite(cost_ground) || !std::isfinite(cost_roof)) continue;
      const float other = filled_raised ? cost_ground : cost_roof, own = filled_raised ? cost_roof : cost_ground;
      if (other > max_cost || own - other < margin) continue;
      height_m[k] = filled_raised ? ground : roof;
      ++changed;
    }
    progress.Advance(++rows_done, "");
  });
  progress.End();
  return changed;
}

}  // namespace

std::vector<float> VisibleAbove(const HeightGrid& g, const std::vector<float>& surface_m,
                                const Eigen::Vector3d& to_camera, double floor_m, int near_cells, bool edge_hides) {
  if (surface_m.size() != static_cast<std::size_t>(g.nx) * g.ny)
    throw Error("dense", "surface", "size " + std::to_string(surface_m.size()) + " is not nx*ny");
  const float lowest = -std::numeric_limits<float>::infinity();
  std::vector<float> out(surface_m.size(), lowest);
  const double horizontal = to_camera.head<2>().norm();
  if (!(horizontal > 1e-9 * to_camera.norm()) || !(to_camera.z() > 0)) return out;  // straight down: nothing hides
  float top = lowest;
  for (float h : surface_m)
    if (std::isfinite(h)) top = std::max(top, h);
  if (!std::isfinite(top)) return out;
  // March toward the camera one cell at a time; the ray rises `rise` per step.
  const double step_i = to_camera.x() / horizontal, step_j = to_camera.y() / horizontal;
  const double rise = g.cell_m * to_camera.z() / horizontal;
  tbb::parallel_for(0, g.ny, [&](int j) {
    for (int i = 0; i < g.nx; ++i) {
      float best = lowest;
      for (int t = 1 + near_cells;; ++t) {
        const double drop = t * rise;
        if (top - drop <= best || top - drop < floor_m) break;  // nothing further can hide the cell
        const int a = static_cast<int>(std::lround(i + t * step_i)), b = static_cast<int>(std::lround(j + t * step_j));
        if (a < 0 || b < 0 || a >= g.nx || b >= g.ny) {
          if (edge_hides) best = static_cast<float>(top - drop);
          break;
        }
        const float h = surface_m[g.Index(a, b)];
        if (std::isfinite(h)) best = std::max(best, static_cast<float>(h - drop));
      }
      out[g.Index(i, j)] = best;
    }
  });
  return out;
}

std::vector<std::uint8_t> OccludedAtGround(const HeightGrid& g, const std::vector<float>& surface_m,
                                           const std::vector<float>& terrain_m,
                                           const std::vector<Eigen::Vector3d>& to_cameras,
                                           const std::vector<std::array<int, 2>>& pairs, double tolerance_m,
                                           double floor_m, bool edge_hides) {
  const std::size_t cells = static_cast<std::size_t>(g.nx) * g.ny;
  if (surface_m.size() != cells || terrain_m.size() != cells)
    throw Error("dense", "surface", "size " + std::to_string(surface_m.size()) + " is not nx*ny");
  const int views = static_cast<int>(to_cameras.size());
  for (const auto& p : pairs)
    if (p[0] < 0 || p[1] < 0 || p[0] >= views || p[1] >= views)
      throw Error("dense", "pair", std::to_string(p[0]) + "-" + std::to_string(p[1]) + " names a view beyond the " +
                                       std::to_string(views) + " given");
  // Per view, the cells whose ground point it sees.
  std::vector<std::vector<std::uint8_t>> sees(to_cameras.size());
  for (int v = 0; v < views; ++v) {
    const std::vector<float> seen_above =
        VisibleAbove(g, surface_m, to_cameras[v], floor_m, 0, edge_hides);
    sees[v].resize(cells);
    for (std::size_t k = 0; k < cells; ++k) sees[v][k] = terrain_m[k] + tolerance_m >= seen_above[k] ? 1 : 0;
  }
  std::vector<std::uint8_t> seen_by_pair(cells, 0);
  for (const auto& p : pairs) {
    const std::vector<std::uint8_t>& a = sees[p[0]];
    const std::vector<std::uint8_t>& b = sees[p[1]];
    for (std::size_t k = 0; k < cells; ++k) seen_by_pair[k] |= a[k] & b[k];
  }
  std::vector<std::uint8_t> occluded(cells, 0);
  for (std::size_t k = 0; k < cells; ++k)
    occluded[k] = !std::isfinite(surface_m[k]) && std::isfinite(terrain_m[k]) && !seen_by_pair[k] ? 1 : 0;
  return occluded;
}

std::vector<float> AggregateSgm(const std::vector<float>& cost, int nx, int ny, int heights, float p1, float p2) {
  if (cost.size() != static_cast<std::size_t>(nx) * ny * heights)
    throw Error("dense", "cost", "volume size " + std::to_string(cost.size()) + " is not nx*ny*heights");
  std::vector<float> total(cost.size(), 0.0f);
  static constexpr int kDirections[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {-1, 1}, {1, -1}, {-1, -1}};
  const DenseKernels& kernels = ActiveKernels();
  for (const auto& d : kDirections) AddSgmDirection(kernels, cost, nx, ny, heights, p1, p2, d[0], d[1], total);
  return total;
}

std::vector<DensePair> SelectDensePairs(const DenseOptions& o, const std::vector<DenseView>& views,
                                        const std::vector<DensePair>& pairs, const Eigen::Vector3d& centre) {
  std::vector<DensePair> kept;
  for (const DensePair& p : pairs) {
    if (p.a < 0 || p.b < 0 || p.a >= static_cast<int>(views.size()) || p.b >= static_cast<int>(views.size()) || p.a == p.b)
      throw Error("dense", "pairs", "pair (" + std::to_string(p.a) + ", " + std::to_string(p.b) + ") names no two views");
    if (p.verified < o.min_pair_matches) continue;
    const Eigen::Vector3d ra = (views[p.a].camera.Centre() - centre).normalized();
    const Eigen::Vector3d rb = (views[p.b].camera.Centre() - centre).normalized();
    const double angle_deg = std::acos(std::clamp(ra.dot(rb), -1.0, 1.0)) * 180.0 / M_PI;
    if (angle_deg >= o.min_pair_angle_deg && angle_deg <= o.max_pair_angle_deg) kept.push_back(p);
  }
  std::stable_sort(kept.begin(), kept.end(), [](const DensePair& x, const DensePair& y) { return x.verified > y.verified; });
  if (kept.size() > static_cast<std::size_t>(o.max_pairs)) kept.resize(o.max_pairs);
  return kept;
}

double AutomaticCellM(const std::vector<DenseView>& views, const Eigen::Vector3d& centre_enu_m) {
  double finest_m = std::numeric_limits<double>::infinity();
  for (const DenseView& v : views) {
    const double depth_m = v.camera.Depth(centre_enu_m);
    if (depth_m > 0) finest_m = std::min(finest_m, depth_m / std::sqrt(v.camera.fx * v.camera.fy));
  }
  if (!std::isfinite(finest_m)) return kDenseCellStepM;
  return kDenseCellStepM * std::max(1.0, std::round(finest_m / kDenseCellStepM));
}

DenseResult RunDenseHeights(const DenseOptions& given, const std::vector<DenseView>& views,
                            const std::vector<DensePair>& pairs, const std::vector<Eigen::Vector3d>& all_points,
                            Progress& progress, const std::optional<GroundBox>& extent) {
  given.Check();
  DenseOptions o = given;
  Stopwatch clock;
  DenseResult result;
  result.report.stage = "dense";
  for (const DenseView& v : views)
    if (v.width_px < 2 || v.height_px < 2 || v.bands < 1 ||
        v.pixels.size() != static_cast<std::size_t>(v.width_px) * v.height_px * v.bands)
      throw Error("dense", v.name, "pixel buffer does not match " + std::to_string(v.width_px) + "x" +
                                       std::to_string(v.height_px) + "x" + std::to_string(v.bands));
  auto degenerate = [&](const std::string& why) {
    result.report.status = StageStatus::kDegenerate;
    result.report.message = why;
    result.report.seconds = clock.Seconds();
    return result;
  };
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3d& p : all_points)
    if (!extent || extent->Contains(p.x(), p.y())) points.push_back(p);
  if (points.size() < 3)
    return degenerate(std::to_string(points.size()) + " tie points" + (extent ? " inside the tile extent" : "") +
                      ": fewer than 3, no extent or height range to sweep");

  // Grid: the tie points' horizontal box, clipped to the extent; sweep
  // range: the heights of the tie points inside.
  Eigen::Vector2d lo = all_points[0].head<2>(), hi = lo;
  for (const auto& p : all_points) {
    lo = lo.cwiseMin(p.head<2>());
    hi = hi.cwiseMax(p.head<2>());
  }
  if (extent) {
    lo = lo.cwiseMax(extent->min_m);
    hi = hi.cwiseMin(extent->max_m);
  }
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  std::vector<double> z;
  for (const auto& p : points) {
    centre += p;
    z.push_back(p.z());
  }
  centre /= static_cast<double>(points.size());
  if (given.cell_m == 0) o.cell_m = AutomaticCellM(views, centre);
  const double z_lo = Quantile(z, o.height_percentile) - o.height_margin_m;
  const double z_hi = Quantile(z, 1.0 - o.height_percentile) + o.height_margin_m;
  // A range longer than max_heights steps (towers, hills) is swept with a
  // coarser step rather than refused: the volume's memory stays bounded and
  // the parabola fit between steps keeps sub-step heights.
  double step_m = o.height_step_m;
  int nh = static_cast<int>(std::ceil((z_hi - z_lo) / step_m)) + 1;
  if (nh > o.max_heights) {
    step_m = (z_hi - z_lo) / (o.max_heights - 1);
    nh = std::min(o.max_heights, static_cast<int>(std::ceil((z_hi - z_lo) / step_m)) + 1);
    result.report.message = fmt::format(
        "tie points span {:.1f} m, more than max_heights {} steps of {:.2f} m: swept in steps of {:.3f} m", z_hi - z_lo,
        o.max_heights, o.height_step_m, step_m);
  }
  HeightGrid& g = result.grid;
  g.cell_m = o.cell_m;
  g.x0_m = lo.x();
  g.y0_m = lo.y();
  g.nx = static_cast<int>(std::floor((hi.x() - lo.x()) / o.cell_m)) + 1;
  g.ny = static_cast<int>(std::floor((hi.y() - lo.y()) / o.cell_m)) + 1;
  const std::size_t cells = static_cast<std::size_t>(g.nx) * g.ny;

  result.pairs_used = SelectDensePairs(o, views, pairs, centre);
  if (result.pairs_used.empty()) return degenerate("no image pair has enough tie points at a usable intersection angle");
  std::vector<int> used_views;
  for (const DensePair& p : result.pairs_used) {
    used_views.push_back(p.a);
    used_views.push_back(p.b);
  }
  std::sort(used_views.begin(), used_views.end());
  used_views.erase(std::unique(used_views.begin(), used_views.end()), used_views.end());
  std::vector<int> slot(views.size(), -1);
  std::vector<GreyImage> grey;
  std::vector<Projection> projection;
  for (int v : used_views) {
    slot[v] = static_cast<int>(grey.size());
    grey.push_back(ToGrey(views[v]));
    projection.push_back(ProjectionOf(views[v].camera));
  }

  auto cells_of = [&](double m) { return std::max(1, static_cast<int>(std::lround(m / o.cell_m))); };
  HoleFillOptions fill;
  fill.radius_cells = cells_of(o.fill_radius_m);
  fill.max_reach_cells = cells_of(o.max_fill_reach_m);
  fill.roof_rim_fraction = static_cast<float>(o.fill_roof_rim_fraction);
  fill.roof_rim_occluded = o.fill_roof_rim_occluded;
  fill.roof_enclosed = o.fill_roof_enclosed;
  fill.far_raised_takes_ground = o.fill_far_raised_ground;
  fill.seen_ground_takes_terrain = o.fill_seen_ground_terrain;
  fill.ground_radius_cells = cells_of(o.fill_ground_radius_m);
  fill.ground_tolerance_m = static_cast<float>(o.fill_ground_tolerance_m);
  fill.ground_max_rise_m = static_cast<float>(o.fill_ground_max_rise_m);
  std::vector<Eigen::Vector3d> to_cameras;
  for (int v : used_views) to_cameras.push_back(views[v].camera.Centre() - centre);
  std::vector<std::array<int, 2>> camera_pairs;  // pairs_used, as indices into to_cameras
  for (const DensePair& p : result.pairs_used) camera_pairs.push_back({slot[p.a], slot[p.b]});
  std::size_t occluded_cells = 0;
  std::vector<std::uint8_t> fill_occluded;  // of the last fill_holes
  auto fill_holes = [&](std::vector<float>& heights) {
    const GroundModel model = GroundModelOf(heights, g.nx, g.ny, fill);
    fill_occluded =
        OccludedAtGround(g, heights, model.terrain_m, to_cameras, camera_pairs, o.visibility_tolerance_m, z_lo,
                         o.fill_edge_hides);
    occluded_cells = static_cast<std::size_t>(std::count(fill_occluded.begin(), fill_occluded.end(), 1));
    return FillHoles(heights, g.nx, g.ny, fill, model, &fill_occluded);
  };
  const Sweep sweep{o, g, z_lo, step_m, nh, result.pairs_used, slot, grey, projection};
  std::vector<float> cost = CostVolume(sweep, nullptr, "dense: sweeping heights", progress);
  CellHeights first = PickHeights(sweep, cost, progress);
  std::size_t visibility_changed = 0;
  if (o.visibility_pass) {
    // The first surface, holes filled, tells which views each candidate
    // point is hidden from; the second sweep scores each height only with
    // the pairs that see it there.
    std::vector<float> surface = first.height_m;
    const std::vector<std::uint8_t> filled = fill_holes(surface);
    for (std::size_t k = 0; k < cells; ++k)
      if (filled[k] && !fill_occluded[k]) surface[k] = kNan;
    const std::vector<std::vector<float>> seen_above =
        SeenAbove(g, surface, to_cameras, z_lo, o.visibility_tolerance_m,
                  o.visibility_near_cells >= 0 ? o.visibility_near_cells : o.window_cells / 2);
    cost = CostVolume(sweep, &seen_above, "dense: sweeping heights the views see", progress);
    CellHeights second = PickHeights(sweep, cost, progress);
    for (std::size_t k = 0; k < cells; ++k)
      if (std::isfinite(second.height_m[k]) && std::isfinite(first.height_m[k]) &&
          std::abs(second.height_m[k] - first.height_m[k]) > 1.0f)
        ++visibility_changed;
    first = std::move(second);
  }
  g.height_m = std::move(first.height_m);
  g.cost = std::move(first.cost);
  const std::size_t low_cost = first.low_cost, speckles = first.speckles;
  std::size_t measured = 0;
  for (float h : g.height_m) measured += std::isfinite(h) ? 1 : 0;
  occluded_cells = 0;
  std::size_t coarse_cells = 0, floating_cells = 0;
  int terrain_trend_terms = 0;
  std::size_t filled_sides_changed = 0;
  g.filled.assign(cells, 0);
  if (o.fill_holes) {
    const GroundModel model = GroundModelOf(g.height_m, g.nx, g.ny, fill);
    terrain_trend_terms = model.terrain_trend_terms;
    FloatingPatchOptions floating;
    floating.max_cells = static_cast<int>(std::lround(o.floating_patch_max_m2 / (o.cell_m * o.cell_m)));
    floating.min_rise_m = static_cast<float>(o.floating_patch_min_rise_m);
    floating_cells = RemoveFloatingPatches(g.height_m, g.nx, g.ny, model.terrain_m, floating);
    measured -= floating_cells;
    const std::vector<std::uint8_t> occluded =
        OccludedAtGround(g, g.height_m, model.terrain_m, to_cameras, camera_pairs, o.visibility_tolerance_m, z_lo,
                         o.fill_edge_hides);
    occluded_cells = static_cast<std::size_t>(std::count(occluded.begin(), occluded.end(), 1));
    std::vector<std::uint8_t> from_coarse(cells, 0);
    if (o.coarse_factor > 1) {
      const std::vector<float> coarse = CoarseSweepHeights(sweep, centre, progress);
      for (std::size_t k = 0; k < cells; ++k)
        if (!std::isfinite(g.height_m[k]) && !occluded[k] && std::isfinite(coarse[k])) {
          g.height_m[k] = coarse[k];
          from_coarse[k] = 1;
          ++coarse_cells;
        }
    }
    const std::vector<float> measured_m = g.height_m;  // coarse heights included: they are a surface
    g.filled = FillHoles(g.height_m, g.nx, g.ny, fill, model, &occluded);
    if (o.decide_filled_sides) {
      std::vector<std::uint8_t> candidates = g.filled;
      for (std::size_t k = 0; k < cells; ++k) candidates[k] &= from_coarse[k] ? 0 : 1;
      filled_sides_changed = DecideFilledSides(sweep, to_cameras, NadirFirst(views, used_views, centre), measured_m,
                                               model.terrain_m, candidates, fill.radius_cells, g.height_m, progress);
    }
    // Coarse heights count as filled: not measured at the grid's own scale.
    for (std::size_t k = 0; k < cells; ++k) g.filled[k] |= from_coarse[k];
  }

  // Colour from the most nadir view that sees the cell.
  std::vector<int> by_elevation(views.size());
  std::iota(by_elevation.begin(), by_elevation.end(), 0);
  auto elevation = [&](int v) { return (views[v].camera.Centre() - centre).normalized().z(); };
  std::sort(by_elevation.begin(), by_elevation.end(), [&](int a, int b) { return elevation(a) > elevation(b); });
  g.rgb.assign(cells, {0, 0, 0});
  std::size_t valid = 0;
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = g.Index(i, j);
      if (!std::isfinite(g.height_m[k])) continue;
      ++valid;
      const Eigen::Vector3d world(g.x0_m + i * g.cell_m, g.y0_m + j * g.cell_m, g.height_m[k]);
      for (int v : by_elevation) {
        const DenseView& view = views[v];
        const Eigen::Vector2d px = view.camera.Project(world);
        const int u = static_cast<int>(std::lround(px.x())), w = static_cast<int>(std::lround(px.y()));
        if (u < 0 || w < 0 || u >= view.width_px || w >= view.height_px) continue;
        const float* p = view.pixels.data() + (static_cast<std::size_t>(w) * view.width_px + u) * view.bands;
        if (!std::isfinite(p[0])) continue;  // no data there: the next view
        for (int b = 0; b < 3; ++b)
          g.rgb[k][b] = static_cast<std::uint8_t>(std::clamp(p[std::min(b, view.bands - 1)], 0.0f, 255.0f));
        break;
      }
    }

  StageReport& r = result.report;
  r.metrics["cell_m"] = o.cell_m;
  r.metrics["cells"] = static_cast<double>(cells);
  r.metrics["heights"] = nh;
  r.metrics["height_step_m"] = step_m;
  r.metrics["height_min_m"] = z_lo;
  r.metrics["height_max_m"] = z_hi;
  r.metrics["pairs"] = static_cast<double>(result.pairs_used.size());
  r.metrics["views"] = static_cast<double>(used_views.size());
  r.metrics["valid_fraction"] = static_cast<double>(measured) / static_cast<double>(cells);
  r.metrics["filled_fraction"] = static_cast<double>(valid - measured) / static_cast<double>(cells);
  r.metrics["rejected_cost_fraction"] = 1.0 - static_cast<double>(low_cost) / static_cast<double>(cells);
  r.metrics["rejected_speckle_fraction"] = static_cast<double>(speckles) / static_cast<double>(cells);
  r.metrics["coarse_fraction"] = static_cast<double>(coarse_cells) / static_cast<double>(cells);
  r.metrics["floating_removed_fraction"] = static_cast<double>(floating_cells) / static_cast<double>(cells);
  r.metrics["occluded_fraction"] = static_cast<double>(occluded_cells) / static_cast<double>(cells);
  r.metrics["terrain_trend_terms"] = terrain_trend_terms;
  r.metrics["filled_sides_changed_fraction"] = static_cast<double>(filled_sides_changed) / static_cast<double>(cells);
  r.metrics["visibility_changed_fraction"] = static_cast<double>(visibility_changed) / static_cast<double>(cells);
  r.seconds = clock.Seconds();
  return result;
}

}  // namespace skyfall
