// Helpers shared by the point cloud tests (point_cloud_test.cpp, laz_test.cpp).
#pragma once

#include <cpl_conv.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "products/point_cloud.h"

namespace skyfall::testing {

// EPSG:32617 (UTM 17N) with the ellipsoidal height as third axis, as WKT2.
inline std::string Utm17nWithHeightWkt() {
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(srs, 32617);
  OSRPromoteTo3D(srs, nullptr);
  char* wkt = nullptr;
  const char* options[] = {"FORMAT=WKT2_2019", nullptr};
  OSRExportToWktEx(srs, &wkt, options);
  std::string text = wkt ? wkt : "";
  CPLFree(wkt);
  OSRDestroySpatialReference(srs);
  return text;
}

struct Bounds {
  double min[3], max[3];
};

// The bounds of the points as given (before quantization).
inline Bounds TrueBounds(const std::vector<LasPoint>& points) {
  Bounds b;
  for (int a = 0; a < 3; ++a) b.min[a] = std::numeric_limits<double>::infinity(), b.max[a] = -b.min[a];
  for (const LasPoint& p : points) {
    const double xyz[3] = {p.easting_m, p.northing_m, p.height_m};
    for (int a = 0; a < 3; ++a) b.min[a] = std::min(b.min[a], xyz[a]), b.max[a] = std::max(b.max[a], xyz[a]);
  }
  return b;
}

}  // namespace skyfall::testing
