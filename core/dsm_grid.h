// The raster every DSM-like product shares: a north-up UTM grid of float
// heights. It lives below the stages so that merging (seams) and products
// (export, comparison) use one type without depending on each other.
#pragma once

#include <cstddef>
#include <vector>

namespace skyfall {

// A north-up raster on a UTM grid. Heights in metres above the ellipsoid,
// NaN where there is no data.
struct DsmGrid {
  int width_px = 0;
  int height_px = 0;
  double upper_left_easting_m = 0;
  double upper_left_northing_m = 0;
  double gsd_m = 0;
  int epsg = 0;
  std::vector<float> height_m;  // row-major, row 0 = north edge

  float At(int col, int row) const { return height_m[static_cast<std::size_t>(row) * width_px + col]; }
};

}  // namespace skyfall
