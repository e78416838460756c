#include "ingest/geo.h"

#include <gtest/gtest.h>
#include <ogr_srs_api.h>

#include <cmath>

#include "core/error.h"

namespace skyfall {
namespace {

// The target for every round trip through the frames.
constexpr double kRoundTripTolM = 1e-6;
// GeographicLib's Krüger series and PROJ's Poder/Engsager UTM both claim
// nanometre accuracy inside a zone; 1e-6 m leaves three orders of margin.
constexpr double kProjAgreementTolM = 1e-6;

struct Site {
  const char* name;
  double lon_deg, lat_deg;
};
// Both hemispheres, near the equator, a zone boundary and a UTM exception zone.
const Site kSites[] = {
    {"jacksonville", -81.6637, 30.3488},   {"sydney", 151.2093, -33.8688},
    {"quito", -78.4678, -0.1807},          {"zone17_18_boundary", -78.00001, 35.0},
    {"oslo_zone32V", 10.7522, 59.9139},    {"cape_town", 18.4241, -33.9249},
};

// Distance between two geodetic points in metres, through ECEF.
double GeodeticDistanceM(const GeodeticPoint& a, const GeodeticPoint& b) {
  const EnuFrame frame(a);
  return frame.EnuFromGeodetic(b).norm();
}

TEST(Geo, EnuRoundTripsWithinAMicrometre) {
  for (const Site& s : kSites) {
    const EnuFrame frame({s.lon_deg, s.lat_deg, 12.0});
    for (double de : {-5000.0, 0.0, 3000.0}) {
      for (double dn : {-4000.0, 2500.0}) {
        for (double up : {-120.0, 0.0, 900.0}) {
          const Eigen::Vector3d enu(de, dn, up);
          const GeodeticPoint g = frame.GeodeticFromEnu(enu);
          EXPECT_LT((frame.EnuFromGeodetic(g) - enu).norm(), kRoundTripTolM) << s.name;
          const GeodeticPoint g2 = frame.GeodeticFromEnu(frame.EnuFromGeodetic(g));
          EXPECT_LT(GeodeticDistanceM(g, g2), kRoundTripTolM) << s.name;
        }
      }
    }
  }
}

TEST(Geo, EnuAxesPointEastNorthUp) {
  const EnuFrame frame({-81.6637, 30.3488, 0.0});
  const Eigen::Vector3d north = frame.EnuFromGeodetic({-81.6637, 30.3588, 0.0});
  const Eigen::Vector3d east = frame.EnuFromGeodetic({-81.6537, 30.3488, 0.0});
  const Eigen::Vector3d up = frame.EnuFromGeodetic({-81.6637, 30.3488, 100.0});
  EXPECT_GT(north.y(), 1100.0);  // 0.01 deg of latitude is ~1109 m
  EXPECT_LT(std::abs(north.x()), 1e-6);
  EXPECT_GT(east.x(), 950.0);    // 0.01 deg of longitude at 30 N is ~962 m
  EXPECT_NEAR(up.z(), 100.0, 1e-9);
  EXPECT_NEAR(up.head<2>().norm(), 0.0, 1e-9);
}

TEST(Geo, StandardZonesAndEpsg) {
  EXPECT_EQ(StandardUtmZone(-81.6637, 30.3488).Epsg(), 32617);  // DFC2019 Jacksonville truth
  EXPECT_EQ(StandardUtmZone(151.2093, -33.8688).Epsg(), 32756);
  EXPECT_EQ(StandardUtmZone(-78.00001, 35.0).zone, 17);
  EXPECT_EQ(StandardUtmZone(-77.99999, 35.0).zone, 18);
  EXPECT_EQ(StandardUtmZone(10.7522, 59.9139).zone, 32);  // Norway exception (32V)
  EXPECT_EQ(StandardUtmZone(5.0, 60.0).zone, 32);
  EXPECT_THROW(StandardUtmZone(0.0, 85.0), Error);
  EXPECT_THROW(StandardUtmZone(std::nan(""), 10.0), Error);
  const UtmZone z = UtmZoneFromEpsg(32755);
  EXPECT_EQ(z.zone, 55);
  EXPECT_FALSE(z.north);
  EXPECT_THROW(UtmZoneFromEpsg(4326), Error);
}

TEST(Geo, UtmRoundTripsInBothHemispheresAndAcrossAZoneBoundary) {
  for (const Site& s : kSites) {
    // The zones of points half a degree east and west: at the boundary site
    // one of them is the neighbouring zone, because a city on a boundary
    // keeps one zone for all its tiles.
    for (UtmZone zone : {StandardUtmZone(s.lon_deg - 0.5, s.lat_deg),
                         StandardUtmZone(s.lon_deg + 0.5, s.lat_deg)}) {
      const Eigen::Vector2d en = UtmFromGeodetic(zone, s.lon_deg, s.lat_deg);
      const Eigen::Vector2d ll = GeodeticFromUtm(zone, en.x(), en.y());
      EXPECT_LT(GeodeticDistanceM({s.lon_deg, s.lat_deg, 0}, {ll.x(), ll.y(), 0}), kRoundTripTolM)
          << s.name << " zone " << zone.zone;
      EXPECT_LT((UtmFromGeodetic(zone, ll.x(), ll.y()) - en).norm(), kRoundTripTolM) << s.name;
    }
  }
}

TEST(Geo, EnuToUtmToEnuRoundTrips) {
  for (const Site& s : kSites) {
    const EnuFrame frame({s.lon_deg, s.lat_deg, 5.0});
    const UtmZone zone = StandardUtmZone(s.lon_deg, s.lat_deg);
    for (const Eigen::Vector3d& enu : {Eigen::Vector3d(-700, 300, 20), Eigen::Vector3d(512, -256, -30)}) {
      const GeodeticPoint g = frame.GeodeticFromEnu(enu);
      const Eigen::Vector2d en = UtmFromGeodetic(zone, g.lon_deg, g.lat_deg);
      const Eigen::Vector2d ll = GeodeticFromUtm(zone, en.x(), en.y());
      const Eigen::Vector3d back = frame.EnuFromGeodetic({ll.x(), ll.y(), g.height_m});
      EXPECT_LT((back - enu).norm(), kRoundTripTolM) << s.name;
    }
  }
}

TEST(Geo, BoundarySiteIsTestedInBothZones) {
  EXPECT_EQ(StandardUtmZone(-78.00001 - 0.5, 35.0).zone, 17);
  EXPECT_EQ(StandardUtmZone(-78.00001 + 0.5, 35.0).zone, 18);
}

TEST(Geo, SouthernPointInANorthernZoneKeepsTheNorthernConvention) {
  // A grid in 17N that reaches just south of the equator: northings go
  // slightly negative instead of jumping by 1e7 m.
  const UtmZone north17{17, true};
  const Eigen::Vector2d en = UtmFromGeodetic(north17, -81.0, -0.001);
  EXPECT_LT(en.y(), 0.0);
  EXPECT_GT(en.y(), -200.0);
  const Eigen::Vector2d ll = GeodeticFromUtm(north17, en.x(), en.y());
  EXPECT_NEAR(ll.y(), -0.001, 1e-12);
}

TEST(Geo, UtmAgreesWithProj) {
  // An independent implementation (PROJ through GDAL's OSR) as the oracle.
  for (const Site& s : kSites) {
    const UtmZone zone = StandardUtmZone(s.lon_deg, s.lat_deg);
    OGRSpatialReferenceH wgs84 = OSRNewSpatialReference(nullptr);
    OGRSpatialReferenceH utm = OSRNewSpatialReference(nullptr);
    OSRImportFromEPSG(wgs84, 4326);
    OSRImportFromEPSG(utm, zone.Epsg());
    OSRSetAxisMappingStrategy(wgs84, OAMS_TRADITIONAL_GIS_ORDER);
    OSRSetAxisMappingStrategy(utm, OAMS_TRADITIONAL_GIS_ORDER);
    OGRCoordinateTransformationH ct = OCTNewCoordinateTransformation(wgs84, utm);
    ASSERT_NE(ct, nullptr);
    double x = s.lon_deg, y = s.lat_deg, z = 0.0;
    ASSERT_TRUE(OCTTransform(ct, 1, &x, &y, &z));
    const Eigen::Vector2d ours = UtmFromGeodetic(zone, s.lon_deg, s.lat_deg);
    EXPECT_NEAR(ours.x(), x, kProjAgreementTolM) << s.name;
    EXPECT_NEAR(ours.y(), y, kProjAgreementTolM) << s.name;
    OCTDestroyCoordinateTransformation(ct);
    OSRDestroySpatialReference(wgs84);
    OSRDestroySpatialReference(utm);
  }
}

}  // namespace
}  // namespace skyfall
