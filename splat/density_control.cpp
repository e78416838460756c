#include "splat/density_control.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <utility>

#include "core/error.h"
#include "core/gaussian_moments.h"
#include "core/format.h"

namespace skyfall {
namespace {

Eigen::Matrix3f RotationOf(const Eigen::Vector4f& q) {
  const Eigen::Vector4f u = q.normalized();
  return Eigen::Quaternionf(u[0], u[1], u[2], u[3]).toRotationMatrix();
}

// Spreads the low 16 bits of v to the even bits of the result.
std::uint32_t SpreadBits(std::uint32_t v) {
  v &= 0xFFFFu;
  v = (v | (v << 8)) & 0x00FF00FFu;
  v = (v | (v << 4)) & 0x0F0F0F0Fu;
  v = (v | (v << 2)) & 0x33333333u;
  v = (v | (v << 1)) & 0x55555555u;
  return v;
}

}  // namespace

void DensityControlOptions::Check() const { CheckOptionRanges(*this, "train"); }

CentreGrid::CentreGrid(const GaussianCloud& cloud, double within_m) : cloud_(cloud), within_m_(within_m) {
  if (!(within_m > 0) || !std::isfinite(within_m))
    throw Error("splat", "coincident radius", FormatDouble(within_m) + " m must be finite and > 0");
  for (std::size_t i = 0; i < cloud.size(); ++i) cubes_[KeyOf(cloud.means[i])].push_back(static_cast<std::uint32_t>(i));
}

CentreGrid::Key CentreGrid::KeyOf(const Eigen::Vector3f& p) const {
  // A non-finite centre goes to one cube of its own, far from every other.
  if (!p.allFinite()) return Key{std::numeric_limits<std::int64_t>::min(), 0, 0};
  return Key{static_cast<std::int64_t>(std::floor(p.x() / within_m_)),
             static_cast<std::int64_t>(std::floor(p.y() / within_m_)),
             static_cast<std::int64_t>(std::floor(p.z() / within_m_))};
}

void DensityControl::Accumulate(const std::vector<int>& radius_px, const std::vector<float>& mean2d_norm,
                                int width_px) {
  for (std::size_t i = 0; i < radius_px.size(); ++i) {
    if (radius_px[i]) {
      stats_.grad_sum[i] += mean2d_norm[i] * 0.5f * static_cast<float>(width_px);
      ++stats_.seen[i];
    }
  }
}

bool DensityControl::Due(int step) const {
  return step >= o_.from_step && step % o_.interval_steps == 0 && step <= o_.until_step + o_.interval_steps;
}

std::vector<std::size_t> DensityControl::Densify(int step, GaussianCloud* cloud, GaussianCloud* moment1,
                                                 GaussianCloud* moment2, std::mt19937_64& rng) {
  const GaussianCloud& c = *cloud;
  const bool grow = step <= o_.until_step;
  GaussianCloud out, m, v;
  std::vector<std::size_t> source;
  std::normal_distribution<float> normal(0.0f, 1.0f);
  int added = 0;
  const float split_scale = static_cast<float>(o_.percent_dense * extent_m_);
  auto keep = [&](std::size_t i) {
    out.Append(c, i);
    m.Append(*moment1, i);
    v.Append(*moment2, i);
    source.push_back(i);
  };
  for (std::size_t i = 0; i < c.size(); ++i) {
    const float opacity = 1.0f / (1.0f + std::exp(-c.opacity_logits[i]));
    const float max_scale = std::exp(c.log_scales[i].maxCoeff());
    if (opacity < o_.min_opacity || max_scale > o_.max_scale_m) continue;
    const float avg_grad = stats_.seen[i] ? stats_.grad_sum[i] / stats_.seen[i] : 0.0f;
    const bool hot = grow && avg_grad >= o_.grad_threshold &&
                     c.size() + added < static_cast<std::size_t>(o_.max_gaussians);
    if (hot && max_scale > split_scale) {
      // Split: two samples from the Gaussian, each 1.6x smaller.
      const Eigen::Matrix3f R = RotationOf(c.rotations[i]);
      const Eigen::Vector3f s = c.log_scales[i].array().exp();
      for (int k = 0; k < 2; ++k) {
        keep(i);
        const Eigen::Vector3f z(normal(rng), normal(rng), normal(rng));
        out.means.back() += R * (s.cwiseProduct(z));
        out.log_scales.back() = (s / 1.6f).array().log();
        m.means.back().setZero();
        v.means.back().setZero();
      }
      ++added;  // two replace one
      continue;
    }
    keep(i);
    if (hot) {  // clone
      keep(i);
      ++added;
    }
  }
  const std::vector<std::size_t> order = SpatialOrder(out);
  *cloud = Gather(out, order);
  *moment1 = Gather(m, order);
  *moment2 = Gather(v, order);
  std::vector<std::size_t> ordered_source(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) ordered_source[k] = source[order[k]];
  stats_.Reset(cloud->size());
  return ordered_source;
}

// [m] smallest standard deviation of a merged Gaussian.
constexpr double kMinMergedSigmaM = 1e-6;

bool DensityControl::MergeDue(int step, int iterations) const {
  return o_.merge_within_m > 0 && step % o_.merge_interval_steps == 0 && step < iterations;
}

namespace {

// The Gaussian that stands for `members` of `c` (see MergeCoincident).
void MergeInto(const GaussianCloud& c, const std::vector<std::size_t>& members, GaussianCloud* out) {
  double transmittance = 1;
  for (std::size_t k : members) transmittance *= 1 - OpacityOfLogit(c.opacity_logits[k]);
  // Opacities are sigmoids, so each weight is > 0.
  const GaussianMoments m = WeightedMoments(c, members, [&](std::size_t k) { return OpacityOfLogit(c.opacity_logits[k]); });
  Eigen::Quaterniond rotation;
  Eigen::Vector3d sigma;
  CovarianceAxes(m.covariance, kMinMergedSigmaM, &rotation, &sigma);
  // An opacity of 1 has no finite logit; 1 - 1e-6 renders the same.
  AppendGaussian(m, rotation, sigma, std::min(1 - transmittance, 1 - 1e-6), out);
}

}  // namespace

std::vector<std::size_t> DensityControl::MergeCoincident(GaussianCloud* cloud, GaussianCloud* moment1,
                                                         GaussianCloud* moment2) {
  const GaussianCloud& c = *cloud;
  const CentreGrid grid(c, o_.merge_within_m);
  std::vector<char> taken(c.size(), 0);
  GaussianCloud out, m, v;
  DensifyStats stats;
  std::vector<std::size_t> source;
  std::vector<std::size_t> members;
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (taken[i]) continue;
    members.assign(1, i);
    if (c.means[i].allFinite()) {
      // Members are alike in shape to the first one, not merely near it.
      const Eigen::Matrix3d cov_i = GaussianCovariance(c, i);
      const double limit = o_.merge_max_shape_difference * cov_i.norm();
      grid.ForEachNear(i, [&](std::size_t j) {
        if (!taken[j] && j > i && (GaussianCovariance(c, j) - cov_i).norm() <= limit) members.push_back(j);
        return true;
      });
    }
    std::size_t keeper = i;
    for (std::size_t k : members) {
      taken[k] = 1;
      if (c.opacity_logits[k] > c.opacity_logits[keeper]) keeper = k;
    }
    if (members.size() == 1) {
      out.Append(c, i);
    } else {
      MergeInto(c, members, &out);
    }
    m.Append(*moment1, keeper);
    v.Append(*moment2, keeper);
    stats.grad_sum.push_back(stats_.grad_sum.empty() ? 0.0f : stats_.grad_sum[keeper]);
    stats.seen.push_back(stats_.seen.empty() ? 0 : stats_.seen[keeper]);
    source.push_back(keeper);
  }
  *cloud = std::move(out);
  *moment1 = std::move(m);
  *moment2 = std::move(v);
  stats_ = std::move(stats);
  return source;
}

// The Gaussians in the order of a Morton (Z-order) curve through their
// centres' x and y. A view of part of the scene (a nadir patch, a crop)
// then reads its Gaussians from a few runs of memory: in a cloud in random
// order, projecting the Gaussians a nadir patch sees waited on memory for
// each of them, longer than culling the whole cloud (decision D-077).
std::vector<std::size_t> SpatialOrder(const GaussianCloud& c) {
  std::vector<std::size_t> order(c.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  if (c.size() <= 1) return order;
  Eigen::Array2f lo = Eigen::Array2f::Constant(std::numeric_limits<float>::max()), hi = -lo;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Eigen::Array2f xy = c.means[i].head<2>().array();
    if (!xy.allFinite()) continue;
    lo = lo.min(xy);
    hi = hi.max(xy);
  }
  constexpr float kCells = 65535.0f;  // 16 bits per axis
  const Eigen::Array2f scale = kCells / (hi - lo).max(1e-6f);
  std::vector<std::pair<std::uint32_t, std::size_t>> keyed;
  keyed.reserve(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Eigen::Array2f xy = c.means[i].head<2>().array();
    Eigen::Array2f q = Eigen::Array2f::Zero();
    if (xy.allFinite()) q = ((xy - lo) * scale).max(0.0f).min(kCells);
    const std::uint32_t key = SpreadBits(static_cast<std::uint32_t>(q.x())) |
                              (SpreadBits(static_cast<std::uint32_t>(q.y())) << 1);
    keyed.emplace_back(key, i);
  }
  std::sort(keyed.begin(), keyed.end());  // ties by index: deterministic
  for (std::size_t k = 0; k < keyed.size(); ++k) order[k] = keyed[k].second;
  return order;
}

GaussianCloud Gather(const GaussianCloud& c, const std::vector<std::size_t>& order) {
  GaussianCloud out;
  for (std::size_t i : order) out.Append(c, i);
  return out;
}

}  // namespace skyfall
