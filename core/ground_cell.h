// The dense height grid's automatic cell, shared by the tiling (which sizes
// tiles in cells) and the dense stage (which sweeps on it).
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

}  // namespace skyfall
