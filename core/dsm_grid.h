// The raster every DSM-like product shares: a north-up UTM grid of float
// heights. It lives below the stages so that merging (seams) and products
// (export, comparison) use one type without depending on each other.
#pragma once

#include <array>
#include <cstddef>
#include <utility>
#include <vector>

#include "core/enum_codec.h"

namespace skyfall {

// What a height raster's values are measured from. Geometry (RPCs, ENU
// frames, the DFC2019 LiDAR) is ellipsoidal; EGM96 is offered for users who
// want orthometric heights; an nDSM is measured above the terrain model.
enum class HeightReference {
  kEllipsoid,     // above the WGS84 ellipsoid: the UTM CRS promoted to 3D (EPSG:4979 heights)
  kEgm96,         // above the EGM96 geoid: compound CRS EPSG:<utm>+5773
  kAboveTerrain,  // above the run's DTM (nDSM): no vertical CRS, stated in the metadata
};
template <>
struct EnumNames<HeightReference> {
  static constexpr std::array<std::pair<HeightReference, const char*>, 3> kNames = {
      {{HeightReference::kEllipsoid, "ellipsoid"},
       {HeightReference::kEgm96, "egm96"},
       {HeightReference::kAboveTerrain, "above_terrain"}}};
};

// A north-up raster on a UTM grid. Heights in metres above `reference`
// (the ellipsoid unless converted for export), NaN where there is no data.
struct DsmGrid {
  int width_px = 0;
  int height_px = 0;
  double upper_left_easting_m = 0;
  double upper_left_northing_m = 0;
  double gsd_m = 0;
  int epsg = 0;
  HeightReference reference = HeightReference::kEllipsoid;
  std::vector<float> height_m;  // row-major, row 0 = north edge

  float At(int col, int row) const { return height_m[static_cast<std::size_t>(row) * width_px + col]; }
};

}  // namespace skyfall
