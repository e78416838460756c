// Stitching independently reconstructed tiles into one scene: every
// Gaussian is brought into the city frame, the tile that owns its ground
// position keeps it (its core, up to the seam line that runs through the
// overlap band where neighbours agree, merge/ownership.h), and OpenVDB
// occupancy grids decide in the overlap bands whether a neighbour's
// Gaussian duplicates geometry the owner already has (removed) or fills a
// hole the owner left (kept).
#pragma once

#include <Eigen/Geometry>
#include <functional>
#include <vector>

#include "core/gaussians.h"
#include "core/option_range.h"
#include "core/stage.h"
#include "core/tile.h"
#include "merge/ownership.h"

namespace skyfall {

struct StitchOptions {
  double voxel_m = 1.0;         // [m] occupancy voxel edge
  // Gaussians more transparent than this neither mark occupancy nor fill
  // holes: near-transparent floaters are not geometry.
  double min_opacity = 0.05;
  // [voxels] a neighbour's Gaussian is a duplicate when the owner's occupancy
  // has an active voxel within this distance (tolerates the sub-metre
  // disagreement of two independent reconstructions of one surface).
  int match_radius_voxels = 1;
  // Occupancy by ground column (true) or by voxel (false). By column, a
  // neighbour's Gaussian over ground the owner covers at any height is a
  // duplicate: where two tiles disagree on a roof's height by more than the
  // match radius, a voxel test keeps both roofs, and the higher one shows
  // in the DSM and renders as a step along the boundary.
  bool occupancy_columns = true;
  SeamLineOptions seam_lines;
  void Check() const;  // throws Error("merge", field, ...)
};
template <class IO> void Visit(IO& io, StitchOptions& o) {
  io("voxel_m", o.voxel_m,
     "Occupancy voxel edge", range::Above(0));
  io("min_opacity", o.min_opacity,
     "Gaussians more transparent than this neither mark occupancy nor fill holes", range::FromBelow(0, 1));
  io("match_radius_voxels", o.match_radius_voxels,
     "A neighbour's Gaussian is a duplicate when the owner's occupancy has an active voxel within this distance",
     range::In(0, 8));
  io("occupancy_columns", o.occupancy_columns,
     "Occupancy by ground column (a neighbour's Gaussian over ground the owner covers, at any height, is a "
     "duplicate); off: by voxel");
  io("seam_lines", o.seam_lines);
}

struct StitchResult {
  GaussianCloud cloud;              // in the city frame (the in-memory stitch only)
  std::vector<int> source_tile;     // per kept Gaussian: index into the input tiles (the in-memory stitch only)
  TileOwnership ownership;          // who kept what where (the seam metric judges steps across it)
  std::size_t kept_in_core = 0;     // owned by the tile they came from (core up to the seam lines)
  std::size_t duplicates_removed = 0;
  std::size_t holes_filled = 0;     // kept from a neighbour where the owner had no geometry
  std::size_t outside_extent = 0;   // beyond the producing tile's extent (unsupported): dropped
  std::size_t transparent_dropped = 0;  // overlap Gaussians below min_opacity: dropped
  std::vector<std::size_t> occupied_voxels_per_tile;  // voxels, or columns (occupancy_columns)
  std::size_t occupied_voxels_union = 0;
  StageReport report;
};

// Rigid transform from one local ENU frame to another (exact: both are
// rotations of ECEF). Identity when the origins are equal.
Eigen::Isometry3d FrameChange(const GeodeticPoint& from_origin, const GeodeticPoint& to_origin);
// Applies it to means, rotations and the degree-1 SH (which rotate with the frame).
GaussianCloud TransformCloud(const GaussianCloud& cloud, const Eigen::Isometry3d& to_from);

// Receives each Gaussian the stitch keeps, in order: the tile it came from
// (index into the source) and the Gaussian (i of `cloud`, city frame).
using StitchSink = std::function<void(std::size_t tile, const GaussianCloud& cloud, std::size_t i)>;

// The streamed stitch: two passes over the tiles (the cores, then the
// overlap bands), each tile visited once per pass; memory holds one tile,
// the occupancy grids and the ownership, whatever the city's size. Kept
// Gaussians go to `keep`, cores first (tile by tile), then the fills.
StitchResult StitchTiles(const StitchOptions& options, const GeodeticPoint& city_origin, const TileSource& tiles,
                         const TileOwnership& ownership, const StitchSink& keep);

// The same in memory: the kept Gaussians in `cloud` and `source_tile`.
// All tiles must come from one tiling (same grid). Output frame: `city_origin`.
// `ownership`: seam lines planned on the tiles' rendered surfaces; without
// it they are planned on the opaque Gaussian centres (PlanSeamLinesOnCentres),
// which suits clouds as dense as the line's cells only.
StitchResult StitchTiles(const StitchOptions& options, const GeodeticPoint& city_origin,
                         const std::vector<TileCloud>& tiles, const TileOwnership* ownership = nullptr);

}  // namespace skyfall
