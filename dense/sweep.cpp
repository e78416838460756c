#include "dense/sweep.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <functional>
#include <optional>

#include "core/error.h"
#include "core/simd.h"
#include "core/simd_target.h"
#include "core/stats.h"

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

namespace dense_detail {
namespace {

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

}  // namespace

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
  g.noise_std = EstimateNoiseStd(g);
  return g;
}

float EstimateNoiseStd(const GreyImage& g) {
  constexpr int kBlock = 16;
  constexpr double kMaskGain = 6.0;  // sqrt of the sum of the mask's squared weights (1 4 1 4 16 4 1 4 1)
  constexpr double kPercentile = 0.10;
  const int w = g.width;
  auto at = [&](int x, int y) { return g.values[static_cast<std::size_t>(y) * w + x]; };
  std::vector<float> block_std;
  for (int by = 1; by + kBlock < g.height; by += kBlock)
    for (int bx = 1; bx + kBlock < w; bx += kBlock) {
      double squares = 0;
      bool finite = true;
      for (int y = by; y < by + kBlock && finite; ++y)
        for (int x = bx; x < bx + kBlock; ++x) {
          const float l = at(x - 1, y - 1) - 2 * at(x, y - 1) + at(x + 1, y - 1) - 2 * at(x - 1, y) + 4 * at(x, y) -
                          2 * at(x + 1, y) + at(x - 1, y + 1) - 2 * at(x, y + 1) + at(x + 1, y + 1);
          if (!std::isfinite(l)) {
            finite = false;
            break;
          }
          squares += static_cast<double>(l) * l;
        }
      if (finite) block_std.push_back(static_cast<float>(std::sqrt(squares / (kBlock * kBlock)) / kMaskGain));
    }
  return block_std.empty() ? 0.0f : static_cast<float>(Quantile(std::move(block_std), kPercentile));
}

Projection ProjectionOf(const PinholeCamera& c) {
  Projection rt;
  rt.leftCols<3>() = c.cam_from_world_rotation;
  rt.col(3) = c.cam_from_world_translation;
  return c.K() * rt;
}

namespace {

// One strip of one height's costs: the strip's rows [j0, j1) and the rows
// their windows reach, [s0, s1), swept as a grid of their own: its first
// and last r rows are border there, but those are the neighbouring strips'
// rows (or the grid's own border), and only [j0, j1) is written to `out`
// (the height's slice of cells). See CostVolume.
void StripCosts(const Sweep& s, const std::vector<std::vector<float>>* seen_above, const DenseKernels& kernels,
                double height, int j0, SweepScratch& t, float* out) {
  const HeightGrid& g = s.grid;
  const std::size_t views = s.grey.size();
  const int r = s.o.window_cells / 2;
  const float trunc = static_cast<float>(s.o.cost_truncation);
  const float min_var = static_cast<float>(s.o.min_std * s.o.min_std);
  const float noise_share = static_cast<float>(s.o.noise_compensation);
  const int j1 = std::min(g.ny, j0 + kStripRows);
  const int s0 = std::max(0, j0 - r), s1 = std::min(g.ny, j1 + r);
  const int rows = s1 - s0;
  const std::size_t first = static_cast<std::size_t>(s0) * g.nx;
  const std::size_t n = static_cast<std::size_t>(rows) * g.nx;
  for (std::size_t v = 0; v < views; ++v) {
    WarpToGrid(kernels, s.grey[v], s.projection[v], g, height, s0, s1, t.warped.data(), t.warp_scratch);
    const float noise_var = noise_share * s.grey[v].noise_std * s.grey[v].noise_std;
    kernels.window_stats(t.warped.data(), g.nx, rows, r, min_var, noise_var, t.stats[v].values.data(),
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
                               b.inv_std.data(), t.visible[ia].data(), t.visible[ib].data(), g.nx, rows, r, trunc,
                               t.sum.data(), t.count.data(), t.ring.data());
    else
      kernels.pair_cost(a.values.data(), b.values.data(), a.mean.data(), b.mean.data(), a.inv_std.data(),
                        b.inv_std.data(), nullptr, nullptr, g.nx, rows, r, trunc, t.sum.data(), nullptr,
                        t.ring.data());
  }
  const float prior = static_cast<float>(s.o.visibility.prior_pairs);
  const float inv_pairs = 1.0f / static_cast<float>(s.pairs.size());
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

}  // namespace

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
  tbb::enumerable_thread_specific<SweepScratch> scratch;
  tbb::parallel_for(0, blocks, [&](int block) {
    SweepScratch& t = scratch.local();
    t.Resize(strip_cells, cells, views, g.nx, r, block_heights, seen_above != nullptr);
    const int d0 = block * block_heights, d1 = std::min(nh, d0 + block_heights);
    for (int d = d0; d < d1; ++d) {
      float* out = t.block.data() + static_cast<std::size_t>(d - d0) * cells;
      for (int j0 = 0; j0 < g.ny; j0 += kStripRows) StripCosts(s, seen_above, kernels, s.Height(d), j0, t, out);
      progress.Advance(++done, "");
    }
    for (std::size_t k = 0; k < cells; ++k)
      for (int d = d0; d < d1; ++d) cost[k * nh + d] = t.block[static_cast<std::size_t>(d - d0) * cells + k];
  });
  progress.End();
  return cost;
}

CellHeights PickHeights(const Sweep& s, const std::vector<float>& cost, Progress& progress) {
  const HeightGrid& g = s.grid;
  const DenseOptions& o = s.o;
  const std::size_t cells = s.Cells();
  const int nh = s.nh;
  progress.Begin("dense: semi-global matching", 0);
  const std::vector<float> total =
      AggregateSgm(cost, g.nx, g.ny, nh, static_cast<float>(o.sgm.p1), static_cast<float>(o.sgm.p2));
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

namespace {

// The grid of a sweep at `factor` times the fine cell, each coarse cell
// centred on its factor x factor fine cells.
HeightGrid CoarseGrid(const HeightGrid& g, int factor) {
  HeightGrid c;
  c.cell_m = g.cell_m * factor;
  c.x0_m = g.x0_m + 0.5 * (factor - 1) * g.cell_m;
  c.y0_m = g.y0_m + 0.5 * (factor - 1) * g.cell_m;
  c.nx = g.nx / factor;
  c.ny = g.ny / factor;
  return c;
}

// Wide windows fatten what they straddle: at a roof's edge the roof's
// texture wins, and a band of ground takes the roof's height. Only cells
// whose neighbours within `reach` cells are measured and lie within
// kSmoothSlope of them keep a height: inside a roof, gabled or flat, or on
// open ground, not near a step.
std::vector<float> SmoothCellsOnly(const std::vector<float>& picked, const HeightGrid& c, int reach) {
  constexpr float kSmoothSlope = 1.0f;  // [m per coarse cell]; a roof of 30 deg rises 0.9 m per 1.5 m cell
  std::vector<float> h(picked.size(), kNan);
  for (int b = 0; b < c.ny; ++b)
    for (int a = 0; a < c.nx; ++a) {
      const float centre = picked[c.Index(a, b)];
      bool smooth = std::isfinite(centre);
      for (int db = -reach; db <= reach && smooth; ++db)
        for (int da = -reach; da <= reach && smooth; ++da) {
          const int x = a + da, y = b + db;
          if (x < 0 || y < 0 || x >= c.nx || y >= c.ny) continue;
          const float n = picked[c.Index(x, y)];
          smooth = std::isfinite(n) && std::abs(n - centre) <= kSmoothSlope * std::max(std::abs(da), std::abs(db));
        }
      if (smooth) h[c.Index(a, b)] = centre;
    }
  return h;
}

}  // namespace

// Heights for the cells of the fine sweep's grid from a sweep at
// coarse_factor times its cell (DenseOptions::coarse_factor), on the views
// blurred to that cell, interpolated bilinearly between coarse cells (the
// nearest where a neighbour has no height); NaN where the coarse sweep has
// none.
CoarseViews BlurForCoarseSweeps(const std::vector<GreyImage>& grey, const std::vector<Projection>& projection,
                                double fine_cell_m, int factor, const Eigen::Vector3d& centre_enu_m) {
  CoarseViews out;
  out.factor = factor;
  out.grey.resize(grey.size());
  const double coarse_cell_m = fine_cell_m * factor;
  tbb::parallel_for(0, static_cast<int>(grey.size()), [&](int v) {
    out.grey[v] = Blurred(grey[v], 0.5 * coarse_cell_m * PixelsPerMetre(projection[v], centre_enu_m));
  });
  return out;
}

std::vector<float> CoarseSweepHeights(const Sweep& fine, const CoarseViews& views, Progress& progress) {
  const HeightGrid& g = fine.grid;
  const int f = views.factor;
  std::vector<float> out(fine.Cells(), kNan);
  const HeightGrid c = CoarseGrid(g, f);
  DenseOptions coarse_options = fine.o;
  coarse_options.window_cells = fine.o.coarse.window_cells;
  if (c.nx <= coarse_options.window_cells || c.ny <= coarse_options.window_cells) return out;
  const Sweep coarse{coarse_options, c, fine.z_lo, fine.step_m, fine.nh, fine.pairs, fine.slot, views.grey, fine.projection};
  const std::vector<float> cost = CostVolume(coarse, nullptr, "dense: sweeping holes at a coarser scale", progress);
  constexpr int kSmoothReach = 2;
  const std::vector<float> h =
      SmoothCellsOnly(PickHeights(coarse, cost, progress).height_m, c, kSmoothReach);
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

std::optional<double> ProbeTopHeight(const Sweep& fine, const CoarseViews& views, double z_top_m,
                                     Progress& progress) {
  const HeightGrid c = CoarseGrid(fine.grid, views.factor);
  DenseOptions probe_options = fine.o;
  probe_options.window_cells = fine.o.coarse.window_cells;
  if (c.nx <= probe_options.window_cells || c.ny <= probe_options.window_cells) return std::nullopt;
  // Half a coarse cell per step: a pair 20 deg apart shifts a fifth of a
  // coarse cell per step, enough to find a surface that the fine sweep
  // then measures at its own step.
  const double step_m = std::max(fine.step_m, 0.5 * c.cell_m);
  const int nh = std::min(fine.o.max_heights, static_cast<int>(std::ceil((z_top_m - fine.z_lo) / step_m)) + 1);
  const Sweep probe{probe_options, c, fine.z_lo, (z_top_m - fine.z_lo) / (nh - 1), nh, fine.pairs, fine.slot,
                    views.grey, fine.projection};
  const std::vector<float> cost = CostVolume(probe, nullptr, "dense: probing for surfaces above the tie points", progress);
  constexpr int kProbeSmoothReach = 1;  // 3 x 3 coarse cells agree: a roof, not a chance match
  std::vector<float> h = SmoothCellsOnly(PickHeights(probe, cost, progress).height_m, c, kProbeSmoothReach);
  h.erase(std::remove_if(h.begin(), h.end(), [](float x) { return !std::isfinite(x); }), h.end());
  constexpr std::size_t kTopCells = 4;  // the top is the 4th highest smooth cell, so one patch cannot set it
  if (h.size() < kTopCells) return std::nullopt;
  std::nth_element(h.begin(), h.begin() + (kTopCells - 1), h.end(), std::greater<float>());
  return h[kTopCells - 1];
}

}  // namespace dense_detail

std::vector<float> AggregateSgm(const std::vector<float>& cost, int nx, int ny, int heights, float p1, float p2) {
  if (cost.size() != static_cast<std::size_t>(nx) * ny * heights)
    throw Error("dense", "cost", "volume size " + std::to_string(cost.size()) + " is not nx*ny*heights");
  std::vector<float> total(cost.size(), 0.0f);
  static constexpr int kDirections[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {-1, 1}, {1, -1}, {-1, -1}};
  const dense_detail::DenseKernels& kernels = dense_detail::ActiveKernels();
  for (const auto& d : kDirections) dense_detail::AddSgmDirection(kernels, cost, nx, ny, heights, p1, p2, d[0], d[1], total);
  return total;
}

}  // namespace skyfall
