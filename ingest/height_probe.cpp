#include "ingest/height_probe.h"

#include <Eigen/LU>
#include <cmath>

#include "core/error.h"
#include "core/format.h"
#include "core/rpc.h"
#include "ingest/radiometry.h"

namespace skyfall {
namespace {

// Grey image box-averaged by `factor`; a cell is valid when its whole box is.
struct GreyImage {
  int width_px = 0, height_px = 0;
  std::vector<float> value;
  std::vector<std::uint8_t> valid;

  // Bilinear sample at (x, y) in this image's pixels (centres at integers);
  // false outside or next to an invalid cell.
  bool Sample(double x, double y, float* out) const {
    if (!(x >= 0 && y >= 0 && x < width_px - 1 && y < height_px - 1)) return false;
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const std::size_t k = static_cast<std::size_t>(y0) * width_px + x0;
    if (!valid[k] || !valid[k + 1] || !valid[k + width_px] || !valid[k + width_px + 1]) return false;
    const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
    const float top = value[k] + fx * (value[k + 1] - value[k]);
    const float bottom = value[k + width_px] + fx * (value[k + width_px + 1] - value[k + width_px]);
    *out = top + fy * (bottom - top);
    return true;
  }
};

GreyImage Downsampled(const NormalizedImage& im, int factor) {
  GreyImage g;
  g.width_px = im.width_px / factor;
  g.height_px = im.height_px / factor;
  g.value.assign(static_cast<std::size_t>(g.width_px) * g.height_px, 0.0f);
  g.valid.assign(g.value.size(), 1);
  for (int y = 0; y < g.height_px * factor; ++y) {
    for (int x = 0; x < g.width_px * factor; ++x) {
      const std::size_t src = static_cast<std::size_t>(y) * im.width_px + x;
      const std::size_t dst = static_cast<std::size_t>(y / factor) * g.width_px + x / factor;
      g.value[dst] += (im.rgb[3 * src] + im.rgb[3 * src + 1] + im.rgb[3 * src + 2]) / (3.0f * factor * factor);
      g.valid[dst] &= im.valid[src];
    }
  }
  return g;
}

struct View {
  const RpcModel* rpc;
  GreyImage grey;
};

// Normalized cross-correlation of two sample lists; nothing when either is flat.
std::optional<double> Ncc(const std::vector<float>& a, const std::vector<float>& b) {
  const double n = static_cast<double>(a.size());
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sa += a[i];
    sb += b[i];
    saa += static_cast<double>(a[i]) * a[i];
    sbb += static_cast<double>(b[i]) * b[i];
    sab += static_cast<double>(a[i]) * b[i];
  }
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
  constexpr double kMinVariance = 1e-6;  // per sample, on a [0, 1] scale: a flat patch has no say
  if (va < kMinVariance * n || vb < kMinVariance * n) return std::nullopt;
  return (sab - sa * sb / n) / std::sqrt(va * vb);
}

// Mean NCC, over patches of the reference view and the other views, of the
// reference patch against where the other view sees the same ground at
// `height_m`. Each patch maps to the ground through the reference RPC's local
// Jacobian at its centre (exact to well under a pixel over a patch).
double Score(const std::vector<View>& views, const std::vector<Eigen::Vector2d>& centres_px,
             const HeightProbeOptions& o, double height_m) {
  const View& ref = views.front();
  const int f = o.downsample, half = o.patch_px / 2;
  double total = 0;
  int count = 0;
  std::vector<float> a, b;
  for (const Eigen::Vector2d& c : centres_px) {
    Eigen::Vector2d lonlat;
    Eigen::Matrix2d J;
    try {
      lonlat = Localize(*ref.rpc, c.x(), c.y(), height_m);
      ref.rpc->Project(lonlat.x(), lonlat.y(), height_m, &J);
    } catch (const Error&) {
      continue;  // this height is outside what the reference RPC can place
    }
    // A 2 x 2 Jacobian: invertible when its determinant is clearly non-zero
    // against the size of its entries.
    const double det = J.determinant();
    if (!(std::abs(det) > 1e-12 * J.squaredNorm())) continue;
    const Eigen::Matrix2d lonlat_from_px = J.inverse();
    for (std::size_t v = 1; v < views.size(); ++v) {
      a.clear();
      b.clear();
      for (int j = -half; j < half; ++j) {
        for (int i = -half; i < half; ++i) {
          // Full-resolution offset of this downsampled cell from the centre.
          const Eigen::Vector2d d(i * f, j * f);
          float va, vb;
          if (!ref.grey.Sample((c.x() + d.x() + 0.5) / f - 0.5, (c.y() + d.y() + 0.5) / f - 0.5, &va)) continue;
          const Eigen::Vector2d q = lonlat + lonlat_from_px * d;
          Eigen::Vector2d p;
          try {
            p = views[v].rpc->Project(q.x(), q.y(), height_m);
          } catch (const Error&) {
            continue;
          }
          if (!views[v].grey.Sample((p.x() + 0.5) / f - 0.5, (p.y() + 0.5) / f - 0.5, &vb)) continue;
          a.push_back(va);
          b.push_back(vb);
        }
      }
      if (a.size() * 2 < static_cast<std::size_t>(o.patch_px * o.patch_px)) continue;  // mostly unseen
      if (const auto ncc = Ncc(a, b)) {
        total += *ncc;
        ++count;
      }
    }
  }
  return count > 0 ? total / count : -1.0;
}

}  // namespace

void HeightProbeOptions::Check() const {
  auto need = [](bool ok, const char* field, double v) {
    if (!ok) throw Error("height_probe", field, FormatDouble(v) + " is out of range");
  };
  need(max_images >= 2, "max_images", max_images);
  need(downsample >= 1, "downsample", downsample);
  need(patch_px >= 4, "patch_px", patch_px);
  need(patches_per_side >= 1, "patches_per_side", patches_per_side);
  need(coarse_step_m > 0 && std::isfinite(coarse_step_m), "coarse_step_m", coarse_step_m);
  need(fine_step_m > 0 && fine_step_m <= coarse_step_m, "fine_step_m", fine_step_m);
  need(min_score > -1 && min_score < 1, "min_score", min_score);
  need(max_image_mpx > 0, "max_image_mpx", max_image_mpx);
}

std::optional<HeightProbe> ProbeSceneHeight(const std::vector<ImageRecord>& images, const HeightProbeOptions& o) {
  o.Check();
  std::vector<View> views;
  for (const ImageRecord& im : images) {
    if (static_cast<int>(views.size()) == o.max_images) break;
    if (static_cast<double>(im.width_px) * im.height_px > o.max_image_mpx * 1e6) continue;
    try {
      views.push_back({&im.rpc, Downsampled(ReadNormalizedImage(im.path, im.radiometry), o.downsample)});
    } catch (const Error&) {
      continue;  // an unreadable image has no say; ingest reports it elsewhere
    }
  }
  if (views.size() < 2) return std::nullopt;

  const ImageRecord& ref = images.front();
  std::vector<Eigen::Vector2d> centres_px;
  for (int j = 0; j < o.patches_per_side; ++j)
    for (int i = 0; i < o.patches_per_side; ++i)
      centres_px.emplace_back(ref.width_px * (0.25 + 0.5 * (i + 0.5) / o.patches_per_side),
                              ref.height_px * (0.25 + 0.5 * (j + 0.5) / o.patches_per_side));

  const double lo = ref.rpc.height_off - std::abs(ref.rpc.height_scale);
  const double hi = ref.rpc.height_off + std::abs(ref.rpc.height_scale);
  HeightProbe best{ref.rpc.height_off, -2.0};
  auto sweep = [&](double from, double to, double step) {
    for (double h = from; h <= to + 1e-9; h += step) {
      const double s = Score(views, centres_px, o, h);
      if (s > best.score) best = {h, s};
    }
  };
  sweep(lo, hi, o.coarse_step_m);
  const double around = best.height_m;
  sweep(around - 2 * o.coarse_step_m, around + 2 * o.coarse_step_m, o.fine_step_m);
  if (best.score < o.min_score) return std::nullopt;
  return best;
}

}  // namespace skyfall
