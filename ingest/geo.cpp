#include "ingest/geo.h"

#include <GeographicLib/Geocentric.hpp>
#include <GeographicLib/UTMUPS.hpp>
#include <cmath>

#include "core/error.h"
#include "core/format.h"

namespace skyfall {

EnuFrame::EnuFrame(const GeodeticPoint& origin) : origin_(origin) {
  const auto& earth = GeographicLib::Geocentric::WGS84();
  std::vector<double> rot(9);  // ECEF-from-ENU, row-major
  earth.Forward(origin.lat_deg, origin.lon_deg, origin.height_m, ecef_origin_m_.x(),
                ecef_origin_m_.y(), ecef_origin_m_.z(), rot);
  Eigen::Matrix3d ecef_from_enu;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) ecef_from_enu(r, c) = rot[3 * r + c];
  enu_from_ecef_ = ecef_from_enu.transpose();
}

Eigen::Vector3d EnuFrame::EnuFromGeodetic(const GeodeticPoint& p) const {
  Eigen::Vector3d ecef;
  GeographicLib::Geocentric::WGS84().Forward(p.lat_deg, p.lon_deg, p.height_m, ecef.x(), ecef.y(),
                                             ecef.z());
  // Subtract before rotating: both terms are ~6.4e6 m, their difference is
  // small and exact enough in double.
  return enu_from_ecef_ * (ecef - ecef_origin_m_);
}

GeodeticPoint EnuFrame::GeodeticFromEnu(const Eigen::Vector3d& enu_m) const {
  const Eigen::Vector3d ecef = ecef_origin_m_ + enu_from_ecef_.transpose() * enu_m;
  GeodeticPoint p;
  GeographicLib::Geocentric::WGS84().Reverse(ecef.x(), ecef.y(), ecef.z(), p.lat_deg, p.lon_deg,
                                             p.height_m);
  return p;
}

Eigen::Matrix4d EnuFrame::EcefFromEnu() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = enu_from_ecef_.transpose();
  m.topRightCorner<3, 1>() = ecef_origin_m_;
  return m;
}

UtmZone StandardUtmZone(double lon_deg, double lat_deg) {
  if (!std::isfinite(lon_deg) || !std::isfinite(lat_deg) || lat_deg < -80.0 || lat_deg >= 84.0) {
    throw Error("geo", "utm",
                "no UTM zone for lon=" + FormatDouble(lon_deg) + " lat=" + FormatDouble(lat_deg) +
                    " (UTM covers latitudes -80..84)");
  }
  UtmZone z;
  z.zone = GeographicLib::UTMUPS::StandardZone(lat_deg, lon_deg);
  z.north = lat_deg >= 0.0;
  return z;
}

UtmZone UtmZoneFromEpsg(int epsg) {
  UtmZone z;
  if (epsg > 32600 && epsg <= 32660) {
    z.zone = epsg - 32600;
    z.north = true;
  } else if (epsg > 32700 && epsg <= 32760) {
    z.zone = epsg - 32700;
    z.north = false;
  } else {
    throw Error("geo", "epsg", std::to_string(epsg) + " is not a WGS84 / UTM code (32601-32660, 32701-32760)");
  }
  return z;
}

Eigen::Vector2d UtmFromGeodetic(const UtmZone& zone, double lon_deg, double lat_deg) {
  int zone_out = 0;
  bool north_out = true;
  Eigen::Vector2d en;
  try {
    GeographicLib::UTMUPS::Forward(lat_deg, lon_deg, zone_out, north_out, en.x(), en.y(), zone.zone,
                                   /*mgrslimits=*/false);
  } catch (const std::exception& e) {
    throw Error("geo", "utm", std::string(e.what()) + " (lon=" + FormatDouble(lon_deg) +
                                  " lat=" + FormatDouble(lat_deg) + ")");
  }
  // UTMUPS picks the false northing from the point's own hemisphere; make it
  // follow the requested zone instead so a grid keeps one convention.
  if (north_out != zone.north) en.y() += zone.north ? -10000000.0 : 10000000.0;
  return en;
}

Eigen::Vector2d GeodeticFromUtm(const UtmZone& zone, double easting_m, double northing_m) {
  Eigen::Vector2d lonlat;
  try {
    GeographicLib::UTMUPS::Reverse(zone.zone, zone.north, easting_m, northing_m, lonlat.y(),
                                   lonlat.x(), /*mgrslimits=*/false);
  } catch (const std::exception& e) {
    throw Error("geo", "utm", std::string(e.what()));
  }
  return lonlat;
}

}  // namespace skyfall
