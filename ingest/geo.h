// Georeferencing with GeographicLib: the AOI's local ENU frame and UTM.
// Geometry is double everywhere; UTM and ECEF coordinates (1e5-1e7 m) must
// never pass through float.
#pragma once

#include <Eigen/Core>

#include "core/aoi.h"

namespace skyfall {

// A local East-North-Up Cartesian frame tangent to the WGS84 ellipsoid at an
// origin near the AOI. Metres; exact (no small-area approximation).
class EnuFrame {
 public:
  explicit EnuFrame(const GeodeticPoint& origin);

  const GeodeticPoint& origin() const { return origin_; }
  Eigen::Vector3d EnuFromGeodetic(const GeodeticPoint& p) const;
  GeodeticPoint GeodeticFromEnu(const Eigen::Vector3d& enu_m) const;
  // The rigid transform ENU -> ECEF (EPSG:4978) in metres, e.g. a 3D Tiles
  // root transform.
  Eigen::Matrix4d EcefFromEnu() const;

 private:
  GeodeticPoint origin_;
  Eigen::Vector3d ecef_origin_m_;
  Eigen::Matrix3d enu_from_ecef_;  // rows: east, north, up unit vectors in ECEF
};

struct UtmZone {
  int zone = 0;       // 1..60
  bool north = true;  // hemisphere
  int Epsg() const { return (north ? 32600 : 32700) + zone; }
};

// The standard UTM zone of a point (with the Norway/Svalbard exceptions).
// Throws Error outside UTM's latitude range (polar regions use UPS).
UtmZone StandardUtmZone(double lon_deg, double lat_deg);
// Zone of a WGS84 / UTM EPSG code (326zz or 327zz); throws Error otherwise.
UtmZone UtmZoneFromEpsg(int epsg);

// Easting/northing in a given zone (which may differ from the standard one,
// e.g. a city straddling a zone boundary keeps one zone). The false northing
// of the south hemisphere is applied.
Eigen::Vector2d UtmFromGeodetic(const UtmZone& zone, double lon_deg, double lat_deg);
Eigen::Vector2d GeodeticFromUtm(const UtmZone& zone, double easting_m, double northing_m);

}  // namespace skyfall
