// dense.ply, the dense stage's product: one point per cell with a height
// (x y z red green blue matching_cost filled fill_rule views terrain_z, ENU
// metres), and its reader
// for the stages after it (training, view evaluation, the DSM of the dense
// cells).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "dense/dense.h"

namespace skyfall {

// The cells of a dense.ply: ENU positions, colours in [0, 1], whether each
// was filled rather than matched, and the cell size.
// The quality layers (cost, rule, views, terrain) are empty when the file
// predates them.
struct DenseCells {
  double cell_m = 0;
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> colours;
  std::vector<std::uint8_t> filled;
  std::vector<float> cost;              // matching cost at the cell's height
  std::vector<FillRule> fill_rule;      // how the cell got its height
  std::vector<std::uint8_t> views;      // views of the matched pairs that see it
  std::vector<float> terrain_m;         // ENU up of the terrain model; NaN without ground
};

// The text of dense.ply for the cells of `grid` that hold a height.
std::string DenseCellsPly(const HeightGrid& grid);

DenseCells ReadDenseCells(const std::string& dense_ply);

}  // namespace skyfall
