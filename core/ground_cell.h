// What follows the imagery's ground sampling distance (GSD): the dense height
// grid's automatic cell, shared by the tiling (which sizes tiles in cells) and
// the dense stage (which sweeps on it), the training images' automatic
// downscale and the initial Gaussians' automatic spacing.
#pragma once

#include <algorithm>
#include <cmath>

namespace skyfall {

// Cells are whole multiples of this [m].
constexpr double kDenseCellStepM = 0.5;

// The automatic cell for imagery whose finest view samples the ground at
// `finest_gsd_m`: the multiple of kDenseCellStepM nearest half the GSD, at
// least kDenseCellStepM. Sub-metre sensors (WorldView-3's 0.31 m,
// Pleiades' 0.5 m) keep the 0.5 m cells every dense setting was measured
// with; a 2.1 m sensor gets 1 m cells: at one cell per pixel a 5-cell NCC
// window spans 10 m and fattens a 10-20 m building by a cell on every side,
// and edges fall on a 2 m lattice (decision D-116). A GSD that is not
// positive and finite gets kDenseCellStepM.
inline double DenseCellForGsdM(double finest_gsd_m) {
  if (!(finest_gsd_m > 0) || !std::isfinite(finest_gsd_m)) return kDenseCellStepM;
  return kDenseCellStepM * std::max(1.0, std::round(0.5 * finest_gsd_m / kDenseCellStepM));
}

// Imagery at least this coarse [m] trains at its own resolution.
constexpr double kTrainAtFullResolutionGsdM = 1.0;

// The automatic training downscale for imagery whose finest view samples the
// ground at `finest_gsd_m`: 2 for sub-metre sensors (1 m pixels or finer,
// the setting every sub-metre figure was measured with), 1 from
// kTrainAtFullResolutionGsdM up. Halving a 2.1 m image gives 4.2 m pixels, four
// times the 1 m dense cells the Gaussians start from, and the trained DSM
// lost detail the dense heights had (decision D-133). A GSD that is not
// positive and finite gets 2.
inline int TrainDownscaleForGsdM(double finest_gsd_m) {
  if (!(finest_gsd_m > 0) || !std::isfinite(finest_gsd_m)) return 2;
  return finest_gsd_m >= kTrainAtFullResolutionGsdM ? 1 : 2;
}

// The automatic spacing of a dense start's Gaussians for a dense grid of
// `dense_cell_m`: two cells, at least kMinInitSpacingM. Sub-metre sensors'
// 0.5 m cells give the 1 m every sub-metre figure was measured with; a 2.1 m
// sensor's 1 m cells give 2 m, one Gaussian per pixel: at one per 1 m cell,
// four Gaussians shared each pixel, stayed faint (median opacity 0.25) and
// let the ground through the roofs (decision D-153). A cell that is not
// positive and finite gets kMinInitSpacingM.
constexpr double kMinInitSpacingM = 1.0;
inline double InitSpacingForDenseCellM(double dense_cell_m) {
  if (!(dense_cell_m > 0) || !std::isfinite(dense_cell_m)) return kMinInitSpacingM;
  return std::max(kMinInitSpacingM, 2.0 * dense_cell_m);
}

}  // namespace skyfall
