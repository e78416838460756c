#include "splat/rasterizer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/error.h"
#include "core/format.h"
#include "splat/lanes.h"

namespace skyfall {
namespace {

// Expected depth is defined only where enough opacity accumulated.
constexpr double kMinAlphaForDepth = 1e-4;

Eigen::Matrix3d QuaternionToMatrix(const Eigen::Vector4d& q) {  // normalized (w, x, y, z)
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  Eigen::Matrix3d R;
  R << 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
      2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
      2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y);
  return R;
}

// Everything about one Gaussian's projection, in double.
struct Projection {
  bool visible = false;
  Eigen::Vector3d cam;          // camera-frame mean
  Eigen::Matrix<double, 2, 3> J;  // d(u, v)/d(cam)
  Eigen::Matrix3d rotation;     // from the normalized quaternion
  Eigen::Vector3d scale;
  Eigen::Matrix3d sigma;        // 3D covariance (world)
  Eigen::Matrix2d cov;          // 2D covariance incl. dilation
  Eigen::Vector2d uv;
  Eigen::Vector3d view_dir;     // unit, from the camera centre to the mean
  double view_distance = 0;
  Eigen::Vector3d rgb;
  Eigen::Vector3d sh_rgb;       // the SH colour before the appearance transform
  std::uint8_t clamped = 0;
  double opacity = 0;
};

template <typename T>
Projection Project(const GaussianCloudT<T>& cloud, std::size_t i, const PinholeCamera& cam,
                   const Eigen::Vector3d& centre, const RasterOptions& o, const std::vector<ColourAffine<T>>* affine) {
  Projection p;
  const Eigen::Vector3d mean = cloud.means[i].template cast<double>();
  p.cam = cam.cam_from_world_rotation * mean + cam.cam_from_world_translation;
  const double x = p.cam.x(), y = p.cam.y(), z = p.cam.z();
  if (!(z > o.near_m)) return p;
  p.J << cam.fx / z, cam.skew / z, -(cam.fx * x + cam.skew * y) / (z * z), 0.0, cam.fy / z, -cam.fy * y / (z * z);
  p.uv = Eigen::Vector2d(cam.fx * x / z + cam.skew * y / z + cam.cx, cam.fy * y / z + cam.cy);
  const Eigen::Vector4d q = cloud.rotations[i].template cast<double>();
  const double qn = q.norm();
  if (!(qn > 0) || !std::isfinite(qn)) return p;
  p.rotation = QuaternionToMatrix(q / qn);
  p.scale = cloud.log_scales[i].template cast<double>().array().exp();
  const Eigen::Matrix3d M = p.rotation * p.scale.asDiagonal();
  p.sigma = M * M.transpose();
  const Eigen::Matrix<double, 2, 3> Tm = p.J * cam.cam_from_world_rotation;
  p.cov = Tm * p.sigma * Tm.transpose();
  p.cov(0, 0) += o.dilation_px2;
  p.cov(1, 1) += o.dilation_px2;
  if (!(p.cov.determinant() > 0) || !p.uv.allFinite()) return p;
  const double gx = o.guard_band * cam.width_px, gy = o.guard_band * cam.height_px;
  if (p.uv.x() < -gx || p.uv.x() > cam.width_px + gx || p.uv.y() < -gy || p.uv.y() > cam.height_px + gy) return p;
  const Eigen::Vector3d d = mean - centre;
  p.view_distance = d.norm();
  p.view_dir = d / p.view_distance;
  const auto& sh = cloud.sh[i];
  for (int c = 0; c < 3; ++c) {
    double v = kShC0 * sh[c * 4 + 0] + 0.5;
    if (o.sh_degree >= 1) {
      v += kShC1 * (-p.view_dir.y() * sh[c * 4 + 1] + p.view_dir.z() * sh[c * 4 + 2] - p.view_dir.x() * sh[c * 4 + 3]);
    }
    p.sh_rgb[c] = v;
    if (affine) v = static_cast<double>((*affine)[i][c]) * v + static_cast<double>((*affine)[i][3 + c]);
    if (v < 0) {
      v = 0;
      p.clamped |= static_cast<std::uint8_t>(1u << c);
    }
    p.rgb[c] = v;
  }
  p.opacity = 1.0 / (1.0 + std::exp(-static_cast<double>(cloud.opacity_logits[i])));
  p.visible = true;
  return p;
}

// The pixels of a tile inside a Gaussian's ellipse bounding box (tile-local,
// half-open). Forward and backward use the same box, so the cut-off is
// consistent between them.
struct PixelBox {
  int x0, y0, x1, y1;
};
template <typename T>
PixelBox FootprintInTile(const ScreenGaussian<T>& q, int tx0, int ty0, int tw, int th) {
  return {std::max(0, q.x0 - tx0), std::max(0, q.y0 - ty0), std::min(tw, q.x1 - tx0), std::min(th, q.y1 - ty0)};
}

// Tile rows are padded to whole vectors so the blending loops never need a
// scalar remainder.
inline int LaneStride(int tile_px) { return (tile_px + lanes::kLanes - 1) / lanes::kLanes * lanes::kLanes; }
template <typename T>
using LaneInt = std::remove_reference_t<decltype(lanes::Mask<T>()[0])>;

// Four pixels gx..gx+3 of one tile row against one Gaussian: their offsets
// from its centre, its power there, and which of them it blends (inside its
// pixel box, power in [cut, 0]). Shared by the forward and backward loops so
// both blend exactly the same pixels.
template <typename T>
struct FootprintLanes {
  lanes::Vec<T> dx, power;
  lanes::Mask<T> blends;
};
template <typename T>
inline FootprintLanes<T> LanesOfRow(const ScreenGaussian<T>& q, const PixelBox& box, int tx0, int gx, T dy,
                                    T row_power, const lanes::Vec<T>& iota) {
  FootprintLanes<T> f;
  const lanes::Vec<T> px = iota + T(gx);
  f.dx = (q.u - T(tx0 + gx)) - iota;
  f.power = T(-0.5) * q.conic_a * f.dx * f.dx + row_power - q.conic_b * f.dx * dy;
  f.blends = (px >= T(box.x0)) & (px < T(box.x1)) & (f.power <= T(0)) & (f.power >= q.log_alpha_cut);
  return f;
}

template <typename T>
void CheckAffine(const GaussianCloudT<T>& cloud, const std::vector<ColourAffine<T>>* affine) {
  if (affine && affine->size() != cloud.size()) {
    throw Error("raster", "colour_affine",
                std::to_string(affine->size()) + " transforms for " + std::to_string(cloud.size()) + " Gaussians");
  }
}

}  // namespace

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
  o.Check();
  CheckAffine(cloud, colour_affine);
  const int W = cam.width_px, H = cam.height_px;
  if (W < 1 || H < 1) throw Error("raster", "camera", "has an empty image size");
  RenderOutput<T> out;
  out.width_px = W;
  out.height_px = H;
  out.reference_depth_m = cam.cam_from_world_translation.z();
  RasterState<T>& s = out.state;
  const std::size_t n = cloud.size();
  s.screen.assign(n, ScreenGaussian<T>());
  s.radius_px.assign(n, 0);
  const Eigen::Vector3d centre = cam.Centre();
  const int tiles_x = (W + o.tile_px - 1) / o.tile_px, tiles_y = (H + o.tile_px - 1) / o.tile_px;
  std::vector<Eigen::Vector4i> rect(n, Eigen::Vector4i::Zero());  // tile x0, y0, x1, y1 (exclusive)

  // 1. Project every Gaussian (double precision), in parallel.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i < range.end(); ++i) {
      const Projection p = Project(cloud, i, cam, centre, o, colour_affine);
      if (!p.visible) continue;
      const double A = p.cov(0, 0), B = p.cov(0, 1), C = p.cov(1, 1);
      const double det = A * C - B * B;
      // A pixel blends when its power -d^T cov^-1 d / 2 is at least `cut`:
      // within sigma_extent standard deviations (Mahalanobis) and with
      // alpha >= min_alpha. That region is an ellipse; its axis-aligned box
      // has half-widths sqrt(-2 cut * A) and sqrt(-2 cut * C).
      double cut = -0.5 * o.sigma_extent * o.sigma_extent;
      if (o.min_alpha > 0) cut = std::max(cut, std::log(o.min_alpha / p.opacity));
      if (!(cut < 0)) continue;  // too faint to ever reach min_alpha
      const double half_w = std::sqrt(-2.0 * cut * A), half_h = std::sqrt(-2.0 * cut * C);
      const int r = std::max(1, static_cast<int>(std::ceil(std::max(half_w, half_h))));
      const int x0 = std::max(0, static_cast<int>(std::floor((p.uv.x() - half_w) / o.tile_px)));
      const int y0 = std::max(0, static_cast<int>(std::floor((p.uv.y() - half_h) / o.tile_px)));
      const int x1 = std::min(tiles_x, static_cast<int>(std::floor((p.uv.x() + half_w) / o.tile_px)) + 1);
      const int y1 = std::min(tiles_y, static_cast<int>(std::floor((p.uv.y() + half_h) / o.tile_px)) + 1);
      if (x0 >= x1 || y0 >= y1) continue;
      rect[i] = Eigen::Vector4i(x0, y0, x1, y1);
      s.radius_px[i] = r;
      ScreenGaussian<T>& q = s.screen[i];
      q.x0 = static_cast<int>(std::ceil(p.uv.x() - half_w));
      q.y0 = static_cast<int>(std::ceil(p.uv.y() - half_h));
      q.x1 = static_cast<int>(std::floor(p.uv.x() + half_w)) + 1;
      q.y1 = static_cast<int>(std::floor(p.uv.y() + half_h)) + 1;
      q.u = T(p.uv.x());
      q.v = T(p.uv.y());
      q.conic_a = T(C / det);
      q.conic_b = T(-B / det);
      q.conic_c = T(A / det);
      q.opacity = T(p.opacity);
      for (int c = 0; c < 3; ++c) q.rgb[c] = T(p.rgb[c]);
      q.depth = T(p.cam.z() - out.reference_depth_m);
      q.log_alpha_cut = T(cut);
    }
  });

  // 2. Order the visible Gaussians front to back once (ties by index, so the
  // order is deterministic), then bin them into tiles in that order with a
  // counting sort: every tile's list comes out sorted.
  std::vector<std::pair<T, int>> by_depth;
  by_depth.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    if (s.radius_px[i]) by_depth.emplace_back(s.screen[i].depth, static_cast<int>(i));
  tbb::parallel_sort(by_depth.begin(), by_depth.end());
  const int tiles = tiles_x * tiles_y;
  std::vector<int> count(tiles + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!s.radius_px[i]) continue;
    for (int ty = rect[i][1]; ty < rect[i][3]; ++ty)
      for (int tx = rect[i][0]; tx < rect[i][2]; ++tx) ++count[ty * tiles_x + tx + 1];
  }
  std::partial_sum(count.begin(), count.end(), count.begin());
  s.tile_begin.assign(count.begin(), count.end() - 1);
  s.tile_end.assign(count.begin() + 1, count.end());
  s.order.assign(count.back(), 0);
  std::vector<int> fill(s.tile_begin);
  for (const auto& [depth, i] : by_depth) {
    for (int ty = rect[i][1]; ty < rect[i][3]; ++ty)
      for (int tx = rect[i][0]; tx < rect[i][2]; ++tx) s.order[fill[ty * tiles_x + tx]++] = i;
  }

  // 3. Blend front to back, tiles in parallel. Within a tile the loop runs
  // over Gaussians (front to back) and, inside, only over the pixels of the
  // Gaussian's own footprint, with per-pixel compositing state: each
  // Gaussian costs its footprint, not the whole tile. Rows are blended four
  // pixels at a time with lane masks (lanes.h): the per-pixel tests (inside
  // the ellipse, pixel finished) are data-dependent, and as branches they
  // mispredicted often enough to halve the speed.
  out.rgb.assign(3 * static_cast<std::size_t>(W) * H, T(0));
  out.alpha.assign(static_cast<std::size_t>(W) * H, T(0));
  out.depth.assign(static_cast<std::size_t>(W) * H, T(0));
  s.final_transmittance.assign(static_cast<std::size_t>(W) * H, T(1));
  s.entry_blended.assign(s.order.size(), 0);
  if (o.median_depth) out.median_depth.assign(static_cast<std::size_t>(W) * H, std::numeric_limits<T>::quiet_NaN());
  s.contributors.assign(static_cast<std::size_t>(W) * H, 0);
  const T max_alpha = T(o.max_alpha), min_t = T(o.min_transmittance);
  const bool want_median = o.median_depth;
  const int tp = o.tile_px, stride = LaneStride(tp);
  std::atomic<std::size_t> total_blends{0};
  tbb::parallel_for(0, tiles, [&](int t) {
    using V = lanes::Vec<T>;
    using M = lanes::Mask<T>;
    using I = LaneInt<T>;
    const int tx0 = (t % tiles_x) * tp, ty0 = (t / tiles_x) * tp;
    const int tw = std::min(W - tx0, tp), th = std::min(H - ty0, tp);
    // Per-pixel compositing state, rows padded to whole vectors.
    std::vector<T> trans(stride * tp, T(1)), r(stride * tp, T(0)), g(stride * tp, T(0)), b(stride * tp, T(0)),
        d(stride * tp, T(0));
    std::vector<I> last(stride * tp, 0), done(stride * tp, 0);
    M blend_lanes = lanes::Splat<M>(I(0));
    const V iota = lanes::Iota<V>();
    // Once every pixel of the tile is opaque the Gaussians behind change
    // nothing: stop there (most of a dense tile's list).
    int open_pixels = tw * th;
    const int begin = s.tile_begin[t], end = s.tile_end[t];
    for (int k = begin; k < end && open_pixels > 0; ++k) {
      const ScreenGaussian<T>& q = s.screen[s.order[k]];
      const PixelBox box = FootprintInTile(q, tx0, ty0, tw, th);
      const T cc = q.conic_c, op = q.opacity;
      const M position = lanes::Splat<M>(I(k - begin + 1));
      M any_blend = lanes::Splat<M>(I(0));
      for (int py = box.y0; py < box.y1; ++py) {
        const T dy = q.v - T(ty0 + py);
        const T row_power = T(-0.5) * cc * dy * dy;
        for (int gx = box.x0 - box.x0 % lanes::kLanes; gx < box.x1; gx += lanes::kLanes) {
          const int lp = py * stride + gx;
          const FootprintLanes<T> f = LanesOfRow(q, box, tx0, gx, dy, row_power, iota);
          const M ok = f.blends & ~lanes::Load<M>(&done[lp]);
          if (!lanes::Any(ok)) continue;
          const V raw_alpha = op * lanes::Exp(f.power);
          const V alpha = lanes::Select(raw_alpha < max_alpha, raw_alpha, lanes::Splat<V>(max_alpha));
          const V tr = lanes::Load<V>(&trans[lp]);
          const V next = tr * (T(1) - alpha);
          const M finished = ok & (next < min_t);
          const M blend = ok & ~finished;
          if (lanes::Any(finished)) {
            lanes::Store(&done[lp], lanes::Load<M>(&done[lp]) | finished);
            open_pixels -= lanes::Count(finished);
          }
          const V w = lanes::Select(blend, alpha * tr, lanes::Splat<V>(T(0)));
          lanes::Store(&r[lp], lanes::Load<V>(&r[lp]) + w * q.rgb[0]);
          lanes::Store(&g[lp], lanes::Load<V>(&g[lp]) + w * q.rgb[1]);
          lanes::Store(&b[lp], lanes::Load<V>(&b[lp]) + w * q.rgb[2]);
          lanes::Store(&d[lp], lanes::Load<V>(&d[lp]) + w * q.depth);
          lanes::Store(&trans[lp], lanes::Select(blend, next, tr));
          lanes::Store(&last[lp], lanes::Select(blend, position, lanes::Load<M>(&last[lp])));
          if (want_median) {
            const M crossing = blend & (tr > T(0.5)) & (next <= T(0.5));
            for (int i = 0; i < lanes::kLanes; ++i) {
              if (crossing[i]) out.median_depth[static_cast<std::size_t>(ty0 + py) * W + (tx0 + gx + i)] = q.depth;
            }
          }
          blend_lanes -= blend;  // blend is -1 where set
          any_blend |= blend;
        }
      }
      s.entry_blended[k] = lanes::Any(any_blend);
    }
    total_blends += static_cast<std::size_t>(lanes::Sum(blend_lanes));
    for (int py = 0; py < th; ++py) {
      for (int px = 0; px < tw; ++px) {
        const int lp = py * stride + px;
        const std::size_t p = static_cast<std::size_t>(ty0 + py) * W + (tx0 + px);
        s.final_transmittance[p] = trans[lp];
        s.contributors[p] = static_cast<int>(last[lp]);
        out.rgb[3 * p + 0] = r[lp] + trans[lp] * T(o.background[0]);
        out.rgb[3 * p + 1] = g[lp] + trans[lp] * T(o.background[1]);
        out.rgb[3 * p + 2] = b[lp] + trans[lp] * T(o.background[2]);
        const T a = T(1) - trans[lp];
        out.alpha[p] = a;
        out.depth[p] = a >= T(kMinAlphaForDepth) ? d[lp] / a : T(0);
      }
    }
  });
  s.blends = total_blends;
  return out;
}

template <typename T>
GaussianGradients<T> BackwardGaussians(const GaussianCloudT<T>& cloud, const PinholeCamera& cam,
                                       const RasterOptions& o, const RenderOutput<T>& fwd,
                                       const std::vector<T>& d_rgb, const std::vector<T>& d_alpha,
                                       const std::vector<T>& d_depth,
                                       const std::vector<ColourAffine<T>>* colour_affine) {
  CheckAffine(cloud, colour_affine);
  const RasterState<T>& s = fwd.state;
  const int W = fwd.width_px, H = fwd.height_px;
  const std::size_t n = cloud.size();
  const int tiles_x = (W + o.tile_px - 1) / o.tile_px, tiles_y = (H + o.tile_px - 1) / o.tile_px;
  // Screen-space gradients (u, v, conic a, b, c, opacity, r, g, b, depth)
  // per tile-list entry: each tile writes only its own entries, and the sum
  // per Gaussian runs in list order afterwards, so results do not depend on
  // thread scheduling (training reruns and resumes are bit-identical).
  constexpr int kFields = 10;
  std::vector<T> contrib(kFields * s.order.size(), T(0));
  const T max_alpha = T(o.max_alpha);
  const T bg[3] = {T(o.background[0]), T(o.background[1]), T(o.background[2])};

  const int tp = o.tile_px, stride = LaneStride(tp);
  tbb::parallel_for(0, tiles_x * tiles_y, [&](int t) {
    using V = lanes::Vec<T>;
    using M = lanes::Mask<T>;
    using I = LaneInt<T>;
    const int tx0 = (t % tiles_x) * tp, ty0 = (t / tiles_x) * tp;
    const int tw = std::min(W - tx0, tp), th = std::min(H - ty0, tp);
    const int begin = s.tile_begin[t];
    // Per-pixel state of the back-to-front pass, rows padded to whole vectors.
    const int size = stride * tp;
    std::vector<T> trans(size, T(1)), t_final(size, T(1)), dA(size, T(0)), dD(size, T(0));
    std::vector<T> dC[3] = {std::vector<T>(size, T(0)), std::vector<T>(size, T(0)), std::vector<T>(size, T(0))};
    std::vector<T> rest[3] = {std::vector<T>(size, bg[0]), std::vector<T>(size, bg[1]), std::vector<T>(size, bg[2])};
    std::vector<T> rest_d(size, T(0));  // colour and depth behind the current Gaussian
    std::vector<I> last(size, 0);
    int max_last = 0;
    for (int py = 0; py < th; ++py) {
      for (int px = 0; px < tw; ++px) {
        const int lp = py * stride + px;
        const std::size_t p = static_cast<std::size_t>(ty0 + py) * W + (tx0 + px);
        if (!d_rgb.empty()) {
          for (int c = 0; c < 3; ++c) dC[c][lp] = d_rgb[3 * p + c];
        }
        const T a_out = fwd.alpha[p];
        dA[lp] = d_alpha.empty() ? T(0) : d_alpha[p];
        if (!d_depth.empty() && a_out >= T(kMinAlphaForDepth)) {
          // Expected depth E = D / A.
          dD[lp] = d_depth[p] / a_out;
          dA[lp] -= d_depth[p] * fwd.depth[p] / a_out;
        }
        trans[lp] = t_final[lp] = s.final_transmittance[p];
        last[lp] = s.contributors[p];
        max_last = std::max(max_last, s.contributors[p]);
      }
    }
    const V iota = lanes::Iota<V>();
    const V zero = lanes::Splat<V>(T(0));
    for (int k = begin + max_last - 1; k >= begin; --k) {
      if (!s.entry_blended[k]) continue;  // touched no pixel going forwards
      const ScreenGaussian<T>& q = s.screen[s.order[k]];
      const PixelBox box = FootprintInTile(q, tx0, ty0, tw, th);
      const T ca = q.conic_a, cb = q.conic_b, cc = q.conic_c, op = q.opacity;
      const T* col = q.rgb;
      const M position = lanes::Splat<M>(I(k - begin));
      // Lane-wise sums of the screen-space gradient, reduced per Gaussian.
      V g[10];
      for (V& f : g) f = zero;
      M touched = lanes::Splat<M>(I(0));
      for (int py = box.y0; py < box.y1; ++py) {
        const T dy = q.v - T(ty0 + py);
        const T row_power = T(-0.5) * cc * dy * dy;
        for (int gx = box.x0 - box.x0 % lanes::kLanes; gx < box.x1; gx += lanes::kLanes) {
          const int lp = py * stride + gx;
          const FootprintLanes<T> f = LanesOfRow(q, box, tx0, gx, dy, row_power, iota);
          const M ok = f.blends & (position < lanes::Load<M>(&last[lp]));
          if (!lanes::Any(ok)) continue;
          const V& dx = f.dx;
          const V gauss = lanes::Exp(f.power);
          const V raw_alpha = op * gauss;
          const V alpha = lanes::Select(raw_alpha < max_alpha, raw_alpha, lanes::Splat<V>(max_alpha));
          const V inv_one_minus = T(1) / (T(1) - alpha);
          const V tr_behind = lanes::Load<V>(&trans[lp]);
          const V tr = tr_behind * inv_one_minus;  // transmittance in front of this Gaussian
          lanes::Store(&trans[lp], lanes::Select(ok, tr, tr_behind));
          const V w = lanes::Select(ok, alpha * tr, zero);
          V d_alpha_i = zero;
          for (int c = 0; c < 3; ++c) {
            const V dc = lanes::Load<V>(&dC[c][lp]);
            const V behind = lanes::Load<V>(&rest[c][lp]);
            g[6 + c] += w * dc;
            d_alpha_i += (col[c] - behind) * dc;
            lanes::Store(&rest[c][lp], lanes::Select(ok, alpha * col[c] + (T(1) - alpha) * behind, behind));
          }
          const V dd = lanes::Load<V>(&dD[lp]);
          const V behind_d = lanes::Load<V>(&rest_d[lp]);
          g[9] += w * dd;
          d_alpha_i = tr * (d_alpha_i + (q.depth - behind_d) * dd) +
                      lanes::Load<V>(&dA[lp]) * lanes::Load<V>(&t_final[lp]) * inv_one_minus;
          lanes::Store(&rest_d[lp], lanes::Select(ok, alpha * q.depth + (T(1) - alpha) * behind_d, behind_d));
          touched |= ok;
          // A clamped alpha passes no gradient to opacity or shape.
          const M shaped = ok & ~(raw_alpha > max_alpha);
          const V d_power = lanes::Select(shaped, raw_alpha * d_alpha_i, zero);
          g[5] += lanes::Select(shaped, gauss * d_alpha_i, zero);
          g[0] += -d_power * (ca * dx + cb * dy);
          g[1] += -d_power * (cc * dy + cb * dx);
          g[2] += T(-0.5) * d_power * dx * dx;
          g[3] += -d_power * dx * dy;
          g[4] += T(-0.5) * d_power * dy * dy;
        }
      }
      if (lanes::Any(touched)) {
        T* dst = &contrib[kFields * static_cast<std::size_t>(k)];
        for (int f = 0; f < kFields; ++f) dst[f] = lanes::Sum(g[f]);
      }
    }
  });
  std::vector<T> screen(kFields * n, T(0));
  for (std::size_t k = 0; k < s.order.size(); ++k) {
    T* dst = &screen[kFields * static_cast<std::size_t>(s.order[k])];
    const T* src = &contrib[kFields * k];
    for (int f = 0; f < kFields; ++f) dst[f] += src[f];
  }

  // Back through the projection, per Gaussian, in double.
  GaussianGradients<T> out;
  out.d.resize(n);
  out.mean2d_norm.assign(n, T(0));
  if (colour_affine) out.d_colour_affine.assign(n, ColourAffine<T>::Zero());
  const Eigen::Vector3d centre = cam.Centre();
  const Eigen::Matrix3d& Rw = cam.cam_from_world_rotation;
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    out.d.means[i].setZero();
    out.d.log_scales[i].setZero();
    out.d.rotations[i].setZero();
    out.d.opacity_logits[i] = T(0);
    out.d.sh[i].fill(T(0));
    if (!s.radius_px[i]) return;
    const Projection p = Project(cloud, i, cam, centre, o, colour_affine);
    const T* g = &screen[kFields * i];
    const Eigen::Vector2d d_uv(g[0], g[1]);
    out.mean2d_norm[i] = T(d_uv.norm());
    // Colour -> SH and view direction.
    Eigen::Vector3d d_dir = Eigen::Vector3d::Zero();
    const auto& sh = cloud.sh[i];
    for (int c = 0; c < 3; ++c) {
      if (p.clamped & (1u << c)) continue;
      double gc = g[6 + c];
      if (colour_affine) {  // colour = gamma * sh_rgb + beta
        out.d_colour_affine[i][c] = T(gc * p.sh_rgb[c]);
        out.d_colour_affine[i][3 + c] = T(gc);
        gc *= static_cast<double>((*colour_affine)[i][c]);
      }
      out.d.sh[i][c * 4 + 0] = T(kShC0 * gc);
      if (o.sh_degree >= 1) {
        out.d.sh[i][c * 4 + 1] = T(-kShC1 * p.view_dir.y() * gc);
        out.d.sh[i][c * 4 + 2] = T(kShC1 * p.view_dir.z() * gc);
        out.d.sh[i][c * 4 + 3] = T(-kShC1 * p.view_dir.x() * gc);
        d_dir += gc * kShC1 * Eigen::Vector3d(-sh[c * 4 + 3], -sh[c * 4 + 1], sh[c * 4 + 2]);
      }
    }
    Eigen::Vector3d d_mean =
        (Eigen::Matrix3d::Identity() - p.view_dir * p.view_dir.transpose()) * d_dir / p.view_distance;
    // Opacity.
    out.d.opacity_logits[i] = T(g[5] * p.opacity * (1.0 - p.opacity));
    // Conic -> 2D covariance: dL/dCov = -Q G Q with G the symmetric conic gradient.
    const Eigen::Matrix2d Q = p.cov.inverse();
    Eigen::Matrix2d Gq;
    Gq << g[2], 0.5 * g[3], 0.5 * g[3], g[4];
    const Eigen::Matrix2d Gcov = -Q * Gq * Q;
    // Cov = Tm Sigma Tm^T with Tm = J Rw.
    const Eigen::Matrix<double, 2, 3> Tm = p.J * Rw;
    const Eigen::Matrix3d Gsigma = Tm.transpose() * Gcov * Tm;
    const Eigen::Matrix<double, 2, 3> GJ = 2.0 * Gcov * Tm * p.sigma * Rw.transpose();
    // Camera-frame mean: projection, depth and the Jacobian's own dependence.
    const double x = p.cam.x(), y = p.cam.y(), z = p.cam.z(), z2 = z * z, z3 = z2 * z;
    Eigen::Vector3d d_cam = p.J.transpose() * d_uv;
    d_cam.z() += g[9];
    d_cam.x() += GJ(0, 2) * (-cam.fx / z2);
    d_cam.y() += GJ(0, 2) * (-cam.skew / z2) + GJ(1, 2) * (-cam.fy / z2);
    d_cam.z() += GJ(0, 0) * (-cam.fx / z2) + GJ(0, 1) * (-cam.skew / z2) +
                 GJ(0, 2) * (2.0 * (cam.fx * x + cam.skew * y) / z3) + GJ(1, 1) * (-cam.fy / z2) +
                 GJ(1, 2) * (2.0 * cam.fy * y / z3);
    d_mean += Rw.transpose() * d_cam;
    out.d.means[i] = d_mean.cast<T>();
    // Sigma = M M^T, M = R S.
    const Eigen::Matrix3d M = p.rotation * p.scale.asDiagonal();
    const Eigen::Matrix3d GM = 2.0 * Gsigma * M;
    const Eigen::Matrix3d RtGM = p.rotation.transpose() * GM;
    for (int k = 0; k < 3; ++k) out.d.log_scales[i][k] = T(RtGM(k, k) * p.scale[k]);
    const Eigen::Matrix3d G = GM * p.scale.asDiagonal();  // dL/dR
    const Eigen::Vector4d q = cloud.rotations[i].template cast<double>();
    const double qn = q.norm();
    const Eigen::Vector4d u = q / qn;
    const double w = u[0], qx = u[1], qy = u[2], qz = u[3];
    Eigen::Vector4d dq;
    dq[0] = 2 * (-qz * G(0, 1) + qy * G(0, 2) + qz * G(1, 0) - qx * G(1, 2) - qy * G(2, 0) + qx * G(2, 1));
    dq[1] = 2 * (qy * G(0, 1) + qz * G(0, 2) + qy * G(1, 0) - 2 * qx * G(1, 1) - w * G(1, 2) + qz * G(2, 0) +
                 w * G(2, 1) - 2 * qx * G(2, 2));
    dq[2] = 2 * (-2 * qy * G(0, 0) + qx * G(0, 1) + w * G(0, 2) + qx * G(1, 0) + qz * G(1, 2) - w * G(2, 0) +
                 qz * G(2, 1) - 2 * qy * G(2, 2));
    dq[3] = 2 * (-2 * qz * G(0, 0) - w * G(0, 1) + qx * G(0, 2) + w * G(1, 0) - 2 * qz * G(1, 1) + qy * G(1, 2) +
                 qx * G(2, 0) + qy * G(2, 1));
    out.d.rotations[i] = ((dq - u * u.dot(dq)) / qn).cast<T>();
  });
  return out;
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
