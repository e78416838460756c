// Level of detail: a pyramid of ever coarser Gaussian clouds, each built by
// merging the previous level's Gaussians that fall in one voxel (edge
// doubling per level) into a single Gaussian with the same moments.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "core/gaussians.h"
#include "core/option_range.h"

namespace skyfall {

struct LodOptions {
  int max_levels = 6;         // levels after the finest (which is level 0)
  double base_voxel_m = 1.0;  // [m] smallest voxel edge tried; doubles per attempt
  // A level is kept only when it has at most this fraction of the previous
  // level's count; otherwise the voxel doubles again (a sparse scene skips
  // the voxel sizes at which nothing merges).
  double min_reduction = 0.7;
  std::size_t min_gaussians = 16;  // no level coarser than this count
  void Check() const;  // throws Error("lod", field, ...)
};
template <class IO> void Visit(IO& io, LodOptions& o) {
  io("max_levels", o.max_levels,
     "Coarser LOD levels to build", range::In(0, 24));
  io("base_voxel_m", o.base_voxel_m,
     "Smallest voxel edge tried; it doubles per attempt", range::Above(0));
  io("min_reduction", o.min_reduction,
     "A level is kept only when it has at most this fraction of the previous level's Gaussians; otherwise the voxel "
     "doubles again", range::AboveUpTo(0, 1));
  io("min_gaussians", o.min_gaussians,
     "No coarser level is built from a level of this many Gaussians or fewer", range::AtLeast(1));
}

struct LodLevel {
  int level = 0;
  double voxel_m = 0;            // 0 for the finest level
  // [m] largest distance from a finest-level Gaussian's centre to the centre
  // of the Gaussian that represents it at this level.
  double geometric_error_m = 0;
  std::size_t saturated = 0;     // merged Gaussians whose opacity hit the cap (mass not kept)
  Eigen::Vector3d min_m = Eigen::Vector3d::Zero(), max_m = Eigen::Vector3d::Zero();  // bounds of the means
  std::size_t count = 0;         // Gaussians in the level
  GaussianCloud cloud;           // empty where a level is handed on without its Gaussians
};

// The "mass" a Gaussian carries: opacity x the product of its standard
// deviations (the integral of opacity x density, up to (2 pi)^1.5). Merging
// keeps the total mass, the mass-weighted mean and the mass-weighted second
// moment (covariance of the mixture), and mass-weights the colour.
double GaussianMass(const GaussianCloud& cloud, std::size_t i);

// Moment-matched merge of the Gaussians `members` of `cloud`; appended to `out`.
// Returns false when the opacity had to be capped (mass not preserved).
bool MergeGaussians(const GaussianCloud& cloud, const std::vector<std::size_t>& members, GaussianCloud* out);

// Builds the levels one after another and hands each to `emit` when it is
// done, level 0 (`finest` itself) first: `level` holds the figures (its own
// cloud may be empty), `cloud` its Gaussians. Memory holds `finest`, the
// previous level and the one being built, not the whole pyramid.
using LodSink = std::function<void(const LodLevel& level, const GaussianCloud& cloud)>;
void BuildLodLevels(const LodOptions& options, const GaussianCloud& finest, const LodSink& emit);
// Every level in memory, each with its cloud; level 0 is a copy of `finest`.
std::vector<LodLevel> BuildLod(const LodOptions& options, const GaussianCloud& finest);

// Writes DIR/lod_<k>.ply as each level comes (Add), then DIR/lod.json
// (levels, voxel size, geometric error, counts, bounds) on Finish.
class LodWriter {
 public:
  explicit LodWriter(std::string dir) : dir_(std::move(dir)) {}
  void Add(const LodLevel& level, const GaussianCloud& cloud);
  void Finish() const;
  // The levels written so far, without their Gaussians.
  const std::vector<LodLevel>& levels() const { return levels_; }

 private:
  std::string dir_;
  std::vector<LodLevel> levels_;
};

}  // namespace skyfall
