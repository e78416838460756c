#include "merge/lod.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/gaussian_moments.h"
#include "splat/ply.h"

namespace skyfall {
namespace {

// Opacity cap of a merged Gaussian (its logit must stay finite); when the
// merged mass asks for more the Gaussian is saturated and mass is lost.
constexpr double kMaxOpacity = 0.99;
constexpr double kMinOpacity = 1e-6;
// [m] smallest standard deviation of a merged Gaussian (a flat merged sheet
// keeps a finite, tiny thickness).
constexpr double kMinSigmaM = 1e-4;

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

}  // namespace

void LodOptions::Check() const { CheckOptionRanges(*this, "lod"); }

double GaussianMass(const GaussianCloud& cloud, std::size_t i) {
  return Sigmoid(cloud.opacity_logits[i]) * std::exp(static_cast<double>(cloud.log_scales[i].sum()));
}

bool MergeGaussians(const GaussianCloud& cloud, const std::vector<std::size_t>& members, GaussianCloud* out) {
  if (members.size() == 1) {
    out->Append(cloud, members[0]);
    return true;
  }
  const GaussianMoments m = WeightedMoments(cloud, members, [&](std::size_t i) { return GaussianMass(cloud, i); });
  Eigen::Quaterniond rotation;
  Eigen::Vector3d sigma;
  CovarianceAxes(m.covariance, kMinSigmaM, &rotation, &sigma);
  const double wanted_opacity = m.weight / sigma.prod();
  AppendGaussian(m, rotation, sigma, std::clamp(wanted_opacity, kMinOpacity, kMaxOpacity), out);
  return wanted_opacity <= kMaxOpacity;
}

std::vector<LodLevel> BuildLod(const LodOptions& options, const GaussianCloud& finest) {
  options.Check();
  auto bounds = [](LodLevel* l) {
    l->min_m = Eigen::Vector3d::Constant(1e300);
    l->max_m = -l->min_m;
    for (const auto& p : l->cloud.means) {
      l->min_m = l->min_m.cwiseMin(p.cast<double>());
      l->max_m = l->max_m.cwiseMax(p.cast<double>());
    }
    if (l->cloud.size() == 0) l->min_m = l->max_m = Eigen::Vector3d::Zero();
  };
  std::vector<LodLevel> levels(1);
  levels[0].cloud = finest;
  bounds(&levels[0]);
  // representative[i]: index, in the current level, of finest Gaussian i's stand-in.
  std::vector<std::size_t> representative(finest.size());
  for (std::size_t i = 0; i < finest.size(); ++i) representative[i] = i;

  const double extent_m = (levels[0].max_m - levels[0].min_m).norm();
  double voxel_m = options.base_voxel_m;
  for (int k = 1; k <= options.max_levels; voxel_m *= 2) {
    const GaussianCloud& prev = levels.back().cloud;
    if (prev.size() <= options.min_gaussians || voxel_m > 2 * extent_m + options.base_voxel_m) break;
    // Group by voxel: sort (voxel key, index); deterministic order. Doubling
    // grids anchored at 0 nest, so a voxel's members stay in one coarser voxel.
    std::vector<std::pair<std::array<std::int64_t, 3>, std::size_t>> keyed(prev.size());
    for (std::size_t i = 0; i < prev.size(); ++i) {
      std::array<std::int64_t, 3> key;
      for (int a = 0; a < 3; ++a) key[a] = static_cast<std::int64_t>(std::floor(prev.means[i][a] / voxel_m));
      keyed[i] = {key, i};
    }
    std::sort(keyed.begin(), keyed.end());
    LodLevel level;
    level.level = k;
    level.voxel_m = voxel_m;
    std::vector<std::size_t> parent(prev.size());
    for (std::size_t a = 0; a < keyed.size();) {
      std::size_t b = a;
      std::vector<std::size_t> members;
      while (b < keyed.size() && keyed[b].first == keyed[a].first) members.push_back(keyed[b++].second);
      for (std::size_t i : members) parent[i] = level.cloud.size();
      level.saturated += !MergeGaussians(prev, members, &level.cloud);
      a = b;
    }
    // Too little simplification at this voxel size: try the next one.
    if (static_cast<double>(level.cloud.size()) > options.min_reduction * prev.size()) continue;
    for (std::size_t i = 0; i < finest.size(); ++i) {
      representative[i] = parent[representative[i]];
      const double d = (finest.means[i] - level.cloud.means[representative[i]]).cast<double>().norm();
      level.geometric_error_m = std::max(level.geometric_error_m, d);
    }
    bounds(&level);
    levels.push_back(std::move(level));
    ++k;
  }
  return levels;
}

void WriteLod(const std::string& dir, const std::vector<LodLevel>& levels) {
  nlohmann::json list = nlohmann::json::array();
  for (const LodLevel& l : levels) {
    const std::string file = "lod_" + std::to_string(l.level) + ".ply";
    WriteGaussiansPly((std::filesystem::path(dir) / file).string(), l.cloud);
    list.push_back({{"level", l.level},
                    {"file", file},
                    {"voxel_m", l.voxel_m},
                    {"geometric_error_m", l.geometric_error_m},
                    {"count", l.cloud.size()},
                    {"saturated", l.saturated},
                    {"bounds_min_m", {l.min_m.x(), l.min_m.y(), l.min_m.z()}},
                    {"bounds_max_m", {l.max_m.x(), l.max_m.y(), l.max_m.z()}}});
  }
  const nlohmann::json doc = {{"schema", "skyfall.lod/1"},
                              {"frame", "city ENU (see the scene's frame.json)"},
                              {"levels", list}};
  WriteFileAtomic((std::filesystem::path(dir) / "lod.json").string(), doc.dump(2) + "\n");
}

}  // namespace skyfall
