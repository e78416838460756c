// The seam metric of a tiled reconstruction: how much larger the DSM's
// height steps are across tile boundaries than elsewhere.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "core/tile.h"
#include "core/dsm_grid.h"
#include "merge/ownership.h"

namespace skyfall {

// The steps across one border: between two tiles whose owned pixels touch.
struct BorderSeam {
  Eigen::Vector2i tile_a, tile_b;  // (col, row), tile_a the lower index (row-major)
  double mean_step_m = 0;          // mean |h(a) - h(b)| over its pixel pairs
  std::size_t pairs = 0;
};

struct SeamMetric {
  double boundary_mean_step_m = 0;  // mean |h(a) - h(b)| over adjacent pixels owned by different tiles
  double interior_mean_step_m = 0;  // ... over adjacent pixels owned by one tile
  double ratio = 0;                 // boundary / interior (1 = no seam)
  std::size_t boundary_pairs = 0;
  std::size_t interior_pairs = 0;
  std::vector<BorderSeam> borders;  // every pair of tiles that touch, row-major by (tile_a, tile_b)
};

// Adjacent pixel pairs (4-neighbourhood) valid in both; a pixel's tile is
// the owner of its centre in the ENU frame at `enu_origin` (`ownership`:
// the core boundaries as bent by the merge's seam lines, so a step where
// the merge switched tiles counts as a boundary step wherever it lies).
SeamMetric MeasureSeams(const DsmGrid& dsm, const TileOwnership& ownership, const GeodeticPoint& enu_origin);

// A north-up UTM grid (zone of `epsg`) covering `box` of the ENU frame at
// `enu_origin`, with square pixels of `gsd_m`, without data.
DsmGrid GridCovering(const GroundBox& box, const GeodeticPoint& enu_origin, int epsg, double gsd_m);

}  // namespace skyfall
