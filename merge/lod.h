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
#include "splat/ply.h"

namespace skyfall {

struct LodOptions {
  // Levels after the finest (which is level 0): a guard only, the root's
  // count (`min_gaussians`) ends the pyramid first on any city up to tens
  // of kilometres a side.
  int max_levels = 12;
  double base_voxel_m = 1.0;  // [m] smallest voxel edge tried; doubles per attempt
  // A level is kept only when it has at most this fraction of the previous
  // level's count; otherwise the voxel doubles again (a sparse scene skips
  // the voxel sizes at which little merges). Half: a kept level earns its
  // bytes; at 0.7 the 1 m voxel of 0.5 m imagery (0.69-0.71 of level 0)
  // was kept or skipped by chance, and every coarser level moved with it.
  double min_reduction = 0.5;
  // The pyramid ends at the first level of at most this many Gaussians: the
  // root of the 3D Tiles tree, which a whole-city view loads first, so its
  // size does not grow with the city's area.
  std::size_t min_gaussians = 4096;
  // [m] side of the ground blocks the levels are built in, one at a time
  // (raised to base_voxel_m times a power of two, so that voxels nest in
  // blocks; a level whose voxel is larger uses blocks of its voxel).
  double block_m = 128;
  double spill_buffer_mb = 64;  // [MB] Gaussians waiting in memory for their block's file
  void Check() const;  // throws Error("lod", field, ...)
};
template <class IO> void Visit(IO& io, LodOptions& o) {
  io("max_levels", o.max_levels,
     "Coarser LOD levels to build at most (a guard: min_gaussians ends the pyramid first)", range::In(0, 24));
  io("base_voxel_m", o.base_voxel_m,
     "Smallest voxel edge tried; it doubles per attempt", range::Above(0));
  io("min_reduction", o.min_reduction,
     "A level is kept only when it has at most this fraction of the previous level's Gaussians; otherwise the voxel "
     "doubles again", range::AboveUpTo(0, 1));
  io("min_gaussians", o.min_gaussians,
     "The pyramid ends at the first level of this many Gaussians or fewer: the 3D Tiles root a whole-city view loads "
     "first", range::AtLeast(1));
  io("block_m", o.block_m,
     "Side of the ground blocks the levels are built in, one block at a time (memory holds one block, not the city)",
     range::Above(0));
  io("spill_buffer_mb", o.spill_buffer_mb,
     "Gaussians held in memory while they are sorted into their blocks' files", range::Above(0));
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
};

// The "mass" a Gaussian carries: opacity x the product of its standard
// deviations (the integral of opacity x density, up to (2 pi)^1.5). Merging
// keeps the total mass, the mass-weighted mean and the mass-weighted second
// moment (covariance of the mixture), and mass-weights the colour.
double GaussianMass(const GaussianCloud& cloud, std::size_t i);

// Moment-matched merge of the Gaussians `members` of `cloud`; appended to `out`.
// Returns false when the opacity had to be capped (mass not preserved).
bool MergeGaussians(const GaussianCloud& cloud, const std::vector<std::size_t>& members, GaussianCloud* out);

// The finest level, handed to `visit` a chunk at a time in order (a PLY
// file read in chunks, or a cloud in memory as one chunk).
using GaussianChunks = std::function<void(const GaussianChunkVisitor& visit)>;

// Writes DIR/lod_<k>.ply for every level, level 0 being `finest` as given,
// and DIR/lod.json (levels, voxel size, geometric error, counts, bounds);
// returns the levels' figures. Level k merges level k-1's Gaussians that
// share a voxel (the edge doubling per attempt) into one with the same
// moments; the voxels of one level are independent, so each level is built
// block by block (`block_m`) from the previous one's Gaussians sorted into
// blocks on disk (DIR/.lod_spill, removed at the end). Memory holds one
// block and the spill's buffer, whatever the city's size. Within a level
// the Gaussians come block by block (blocks by x then y), each block's in
// voxel order (x, y, z).
std::vector<LodLevel> WriteLodLevels(const LodOptions& options, const GaussianChunks& finest, const std::string& dir);

}  // namespace skyfall
