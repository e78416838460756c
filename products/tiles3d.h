// 3D Tiles 1.1 export of a merged scene, for CesiumJS-style globes: a
// tileset.json whose root transform is the city's ENU -> ECEF matrix, a
// spatial tree over the city with the coarsest LOD level at the root and
// level 0 at the leaves (refine REPLACE, geometricError from each level's
// measured geometric_error_m), and one glTF (GLB) per tile holding its
// Gaussians with KHR_gaussian_splatting compressed by
// KHR_gaussian_splatting_compression_spz_2 (products/spz.h).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "core/gaussians.h"
#include "core/option_range.h"
#include "core/stage.h"

namespace skyfall {

struct Tiles3dOptions {
  double leaf_m = 128;         // [m] a node splits into quadrants while it is wider than this
  int max_fractional_bits = 16;  // finest SPZ position step 2^-bits m (fewer when coordinates are large)
  // [MB] Gaussians waiting for their tile are written to disk when they fill
  // this much memory: with one tile's cloud and one read chunk, it bounds
  // the export's memory whatever the city's size.
  double spill_buffer_mb = 64;
  void Check() const;            // throws Error("3dtiles", field, ...)
};
template <class IO> void Visit(IO& io, Tiles3dOptions& o) {
  io("leaf_m", o.leaf_m,
     "A node splits into quadrants while it is wider than this", range::Above(0));
  io("max_fractional_bits", o.max_fractional_bits,
     "The finest SPZ position step is 2^-bits metres (fewer bits when coordinates are large)", range::In(0, 20));
  io("spill_buffer_mb", o.spill_buffer_mb,
     "Gaussians waiting for their tile's file are written to disk when they fill this much memory (bounds the "
     "export's memory, whatever the city's size)", range::Above(0));
}

struct Tiles3dSummary {
  std::string tileset_path;
  int tiles = 0;           // nodes of the tree
  int contents = 0;        // GLB files
  std::size_t gaussians = 0;
  int levels = 0;          // LOD levels used
  double seconds = 0;
};

// Exports OUT/<city>/scene (lod.json, lod_<k>.ply, frame.json) to out_dir:
// tileset.json (written last) and content/*.glb. The levels are streamed and
// each tile's Gaussians gathered in out_dir/.spill (removed at the end), so
// memory stays near options.spill_buffer_mb. Throws Error naming the missing
// or bad file.
Tiles3dSummary Export3dTiles(const std::string& scene_dir, const std::string& out_dir, const Tiles3dOptions& options,
                             Progress& progress);

// One GLB holding `cloud` as an SPZ-compressed Gaussian splat primitive whose
// positions are in a z-up frame (the node turns them y-up for glTF).
std::vector<std::uint8_t> SplatGlb(const GaussianCloud& cloud, int fractional_bits);

// The glTF node matrix (column-major) that turns z-up content y-up, which a
// 3D Tiles runtime turns back.
inline constexpr double kZUpToYUp[16] = {1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1};

}  // namespace skyfall
