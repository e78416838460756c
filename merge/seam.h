// The seam metric of a tiled reconstruction: how much larger the DSM's
// height steps are across tile boundaries than elsewhere.
#pragma once

#include <cstddef>

#include "core/tile.h"
#include "core/dsm_grid.h"
#include "merge/ownership.h"

namespace skyfall {

struct SeamMetric {
  double boundary_mean_step_m = 0;  // mean |h(a) - h(b)| over adjacent pixels owned by different tiles
  double interior_mean_step_m = 0;  // ... over adjacent pixels owned by one tile
  double ratio = 0;                 // boundary / interior (1 = no seam)
  std::size_t boundary_pairs = 0;
  std::size_t interior_pairs = 0;
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
