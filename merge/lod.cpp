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

namespace {

// The level's count and the bounds of its means.
void Measure(const GaussianCloud& cloud, LodLevel* l) {
  l->count = cloud.size();
  l->min_m = Eigen::Vector3d::Constant(1e300);
  l->max_m = -l->min_m;
  for (const auto& p : cloud.means) {
    l->min_m = l->min_m.cwiseMin(p.cast<double>());
    l->max_m = l->max_m.cwiseMax(p.cast<double>());
  }
  if (cloud.size() == 0) l->min_m = l->max_m = Eigen::Vector3d::Zero();
}

// `prev` merged by voxels of `voxel_m`; parent[i]: the merged Gaussian that
// stands in for prev's Gaussian i. Grouped by sorted (voxel key, index), a
// deterministic order; doubling grids anchored at 0 nest, so a voxel's
// members stay in one coarser voxel.
LodLevel MergeByVoxel(const GaussianCloud& prev, double voxel_m, std::vector<std::size_t>* parent) {
  std::vector<std::pair<std::array<std::int64_t, 3>, std::size_t>> keyed(prev.size());
  for (std::size_t i = 0; i < prev.size(); ++i) {
    std::array<std::int64_t, 3> key;
    for (int a = 0; a < 3; ++a) key[a] = static_cast<std::int64_t>(std::floor(prev.means[i][a] / voxel_m));
    keyed[i] = {key, i};
  }
  std::sort(keyed.begin(), keyed.end());
  LodLevel level;
  level.voxel_m = voxel_m;
  parent->assign(prev.size(), 0);
  for (std::size_t a = 0; a < keyed.size();) {
    std::size_t b = a;
    std::vector<std::size_t> members;
    while (b < keyed.size() && keyed[b].first == keyed[a].first) members.push_back(keyed[b++].second);
    for (std::size_t i : members) (*parent)[i] = level.cloud.size();
    level.saturated += !MergeGaussians(prev, members, &level.cloud);
    a = b;
  }
  return level;
}

}  // namespace

void BuildLodLevels(const LodOptions& options, const GaussianCloud& finest, const LodSink& emit) {
  options.Check();
  LodLevel base;
  Measure(finest, &base);
  emit(base, finest);
  // representative[i]: index, in the current level, of finest Gaussian i's stand-in.
  std::vector<std::size_t> representative(finest.size());
  for (std::size_t i = 0; i < finest.size(); ++i) representative[i] = i;

  const double extent_m = (base.max_m - base.min_m).norm();
  GaussianCloud previous;  // the last level handed on, once there is one
  const GaussianCloud* prev = &finest;
  double voxel_m = options.base_voxel_m;
  std::vector<std::size_t> parent;
  for (int k = 1; k <= options.max_levels; voxel_m *= 2) {
    if (prev->size() <= options.min_gaussians || voxel_m > 2 * extent_m + options.base_voxel_m) break;
    LodLevel level = MergeByVoxel(*prev, voxel_m, &parent);
    level.level = k;
    // Too little simplification at this voxel size: try the next one.
    if (static_cast<double>(level.cloud.size()) > options.min_reduction * prev->size()) continue;
    for (std::size_t i = 0; i < finest.size(); ++i) {
      representative[i] = parent[representative[i]];
      const double d = (finest.means[i] - level.cloud.means[representative[i]]).cast<double>().norm();
      level.geometric_error_m = std::max(level.geometric_error_m, d);
    }
    Measure(level.cloud, &level);
    emit(level, level.cloud);
    previous = std::move(level.cloud);
    prev = &previous;
    ++k;
  }
}

std::vector<LodLevel> BuildLod(const LodOptions& options, const GaussianCloud& finest) {
  std::vector<LodLevel> levels;
  BuildLodLevels(options, finest, [&](const LodLevel& level, const GaussianCloud& cloud) {
    levels.push_back(level);
    if (&cloud != &level.cloud) levels.back().cloud = cloud;
  });
  return levels;
}

namespace {
std::string LodFileName(int level) { return "lod_" + std::to_string(level) + ".ply"; }
}  // namespace

void LodWriter::Add(const LodLevel& level, const GaussianCloud& cloud) {
  WriteGaussiansPly((std::filesystem::path(dir_) / LodFileName(level.level)).string(), cloud);
  levels_.push_back(level);
  levels_.back().cloud = GaussianCloud();
}

void LodWriter::Finish() const {
  nlohmann::json list = nlohmann::json::array();
  for (const LodLevel& l : levels_) {
    list.push_back({{"level", l.level},
                    {"file", LodFileName(l.level)},
                    {"voxel_m", l.voxel_m},
                    {"geometric_error_m", l.geometric_error_m},
                    {"count", l.count},
                    {"saturated", l.saturated},
                    {"bounds_min_m", {l.min_m.x(), l.min_m.y(), l.min_m.z()}},
                    {"bounds_max_m", {l.max_m.x(), l.max_m.y(), l.max_m.z()}}});
  }
  const nlohmann::json doc = {{"schema", "skyfall.lod/1"},
                              {"frame", "city ENU (see the scene's frame.json)"},
                              {"levels", list}};
  WriteFileAtomic((std::filesystem::path(dir_) / "lod.json").string(), doc.dump(2) + "\n");
}

}  // namespace skyfall
