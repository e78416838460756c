#include "merge/seam.h"

#include <cmath>
#include <map>
#include <utility>

#include "core/error.h"
#include "ingest/geo.h"

namespace skyfall {
namespace {

// ENU ground position of a UTM point.
Eigen::Vector2d EnuOfUtm(const EnuFrame& frame, const UtmZone& zone, double e, double n) {
  const Eigen::Vector2d lonlat = GeodeticFromUtm(zone, e, n);
  return frame.EnuFromGeodetic({lonlat.x(), lonlat.y(), frame.origin().height_m}).head<2>();
}

}  // namespace

SeamMetric MeasureSeams(const DsmGrid& dsm, const TileOwnership& ownership, const GeodeticPoint& enu_origin) {
  const TileGrid& grid = ownership.grid();
  if (dsm.width_px < 2 || dsm.height_px < 2) throw Error("merge", "seam metric", "DSM smaller than 2x2 pixels");
  const EnuFrame frame(enu_origin);
  const UtmZone zone = UtmZoneFromEpsg(dsm.epsg);
  // UTM -> ENU is affine to well below a millimetre over a few km (scale
  // varies by ~1e-6 per km): exact at three corners, affine in between.
  const double e0 = dsm.upper_left_easting_m + 0.5 * dsm.gsd_m, n0 = dsm.upper_left_northing_m - 0.5 * dsm.gsd_m;
  const Eigen::Vector2d p00 = EnuOfUtm(frame, zone, e0, n0);
  const Eigen::Vector2d dcol = (EnuOfUtm(frame, zone, e0 + (dsm.width_px - 1) * dsm.gsd_m, n0) - p00) / (dsm.width_px - 1);
  const Eigen::Vector2d drow = (EnuOfUtm(frame, zone, e0, n0 - (dsm.height_px - 1) * dsm.gsd_m) - p00) / (dsm.height_px - 1);
  std::vector<int> owner(static_cast<std::size_t>(dsm.width_px) * dsm.height_px);
  for (int r = 0; r < dsm.height_px; ++r) {
    for (int c = 0; c < dsm.width_px; ++c) {
      const Eigen::Vector2d p = p00 + c * dcol + r * drow;
      const Eigen::Vector2i t = ownership.Owner(p.x(), p.y());
      owner[static_cast<std::size_t>(r) * dsm.width_px + c] = t.y() * grid.cols + t.x();
    }
  }
  double boundary = 0, interior = 0;
  std::map<std::pair<int, int>, std::pair<double, std::size_t>> by_border;  // (a, b) -> (sum, pairs)
  SeamMetric m;
  auto pair = [&](int c0, int r0, int c1, int r1) {
    const float a = dsm.At(c0, r0), b = dsm.At(c1, r1);
    if (!std::isfinite(a) || !std::isfinite(b)) return;
    const double step = std::abs(static_cast<double>(a) - b);
    const int o0 = owner[static_cast<std::size_t>(r0) * dsm.width_px + c0];
    const int o1 = owner[static_cast<std::size_t>(r1) * dsm.width_px + c1];
    if (o0 != o1) {
      boundary += step;
      ++m.boundary_pairs;
      auto& border = by_border[{std::min(o0, o1), std::max(o0, o1)}];
      border.first += step;
      ++border.second;
    } else {
      interior += step;
      ++m.interior_pairs;
    }
  };
  for (int r = 0; r < dsm.height_px; ++r) {
    for (int c = 0; c < dsm.width_px; ++c) {
      if (c + 1 < dsm.width_px) pair(c, r, c + 1, r);
      if (r + 1 < dsm.height_px) pair(c, r, c, r + 1);
    }
  }
  m.boundary_mean_step_m = m.boundary_pairs ? boundary / m.boundary_pairs : NAN;
  m.interior_mean_step_m = m.interior_pairs ? interior / m.interior_pairs : NAN;
  m.ratio = m.boundary_mean_step_m / m.interior_mean_step_m;
  for (const auto& [tiles, sum] : by_border) {
    const Eigen::Vector2i a(tiles.first % grid.cols, tiles.first / grid.cols);
    const Eigen::Vector2i b(tiles.second % grid.cols, tiles.second / grid.cols);
    m.borders.push_back({a, b, sum.first / static_cast<double>(sum.second), sum.second});
  }
  return m;
}

DsmGrid GridCovering(const GroundBox& box, const GeodeticPoint& enu_origin, int epsg, double gsd_m) {
  const EnuFrame frame(enu_origin);
  const UtmZone zone = UtmZoneFromEpsg(epsg);
  Eigen::Vector2d lo(1e18, 1e18), hi(-1e18, -1e18);
  for (int k = 0; k < 4; ++k) {
    const double e = (k & 1) ? box.max_m.x() : box.min_m.x(), n = (k & 2) ? box.max_m.y() : box.min_m.y();
    const GeodeticPoint g = frame.GeodeticFromEnu({e, n, 0.0});
    const Eigen::Vector2d utm = UtmFromGeodetic(zone, g.lon_deg, g.lat_deg);
    lo = lo.cwiseMin(utm);
    hi = hi.cwiseMax(utm);
  }
  DsmGrid g;
  g.epsg = epsg;
  g.gsd_m = gsd_m;
  g.upper_left_easting_m = std::floor(lo.x() / gsd_m) * gsd_m;
  g.upper_left_northing_m = std::ceil(hi.y() / gsd_m) * gsd_m;
  g.width_px = static_cast<int>(std::ceil((hi.x() - g.upper_left_easting_m) / gsd_m));
  g.height_px = static_cast<int>(std::ceil((g.upper_left_northing_m - lo.y()) / gsd_m));
  g.height_m.assign(static_cast<std::size_t>(g.width_px) * g.height_px, NAN);
  return g;
}

}  // namespace skyfall
