// Heights in the vertical frames the pipeline crosses, each its own type, so
// that passing one where another is meant fails to compile:
//  - EllipsoidHeightM: metres above the WGS84 ellipsoid. The frame of RPC
//    HEIGHT_OFF, GeodeticPoint::height_m, the catalogs' scene height range and
//    the DFC2019 truth rasters.
//  - EnuUpM: metres along the up axis of an AOI's local ENU frame, from its
//    origin. The frame of the pinhole cameras, tie points and dense heights.
// Near sea level with an origin near the ground the two differ by metres and
// a slip hides in a height pad; 2,300 m up it puts the scene in the air.
#pragma once

#include "core/aoi.h"

namespace skyfall {

struct EllipsoidHeightM {
  double value = 0.0;
  constexpr EllipsoidHeightM() = default;
  constexpr explicit EllipsoidHeightM(double metres) : value(metres) {}
};

struct EnuUpM {
  double value = 0.0;
  constexpr EnuUpM() = default;
  constexpr explicit EnuUpM(double metres) : value(metres) {}
};

// The ENU up coordinate of an ellipsoidal height above the frame's origin.
// Away from the origin the ellipsoid falls below the tangent plane by
// d^2 / (2 R): 5 mm at 256 m, 8 cm at 1 km, so a height range of a tile or a
// city converts exactly enough at the origin.
inline EnuUpM EnuUpAtOrigin(EllipsoidHeightM h, const GeodeticPoint& enu_origin) {
  return EnuUpM(h.value - enu_origin.height_m);
}

}  // namespace skyfall
