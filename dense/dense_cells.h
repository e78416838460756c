// dense.ply, the dense stage's product: one point per cell with a height
// (x y z red green blue matching_cost filled, ENU metres), and its reader
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
struct DenseCells {
  double cell_m = 0;
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> colours;
  std::vector<std::uint8_t> filled;
};

// The text of dense.ply for the cells of `grid` that hold a height.
std::string DenseCellsPly(const HeightGrid& grid);

DenseCells ReadDenseCells(const std::string& dense_ply);

}  // namespace skyfall
