#include "synthesis/orbit.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/format.h"

namespace skyfall {

void OrbitOptions::Check() const { CheckOptionRanges(*this, "idu", "orbit"); }

namespace {
double EpisodeFraction(const OrbitOptions& o, int episode) {
  return o.episodes > 1 ? static_cast<double>(episode) / (o.episodes - 1) : 0.0;
}
}  // namespace

double EpisodeElevationDeg(const OrbitOptions& o, int episode) {
  const double t = EpisodeFraction(o, episode);
  return o.elevation_start_deg + t * (o.elevation_end_deg - o.elevation_start_deg);
}

double EpisodeRadiusM(const OrbitOptions& o, const GroundBox& core, int episode) {
  const double t = EpisodeFraction(o, episode);
  const double side_m = std::max(core.Width(), core.Height());
  return std::max(o.min_radius_m, side_m * (o.radius_start_per_core + t * (o.radius_end_per_core - o.radius_start_per_core)));
}

std::vector<Eigen::Vector3d> LookAtGrid(const GroundBox& core, int grid,
                                        const std::function<double(double, double)>& surface_height_m,
                                        double fallback_height_m) {
  std::vector<Eigen::Vector3d> points;
  for (int j = 0; j < grid; ++j) {
    for (int i = 0; i < grid; ++i) {
      const double east = core.min_m.x() + (i + 0.5) * core.Width() / grid;
      const double north = core.min_m.y() + (j + 0.5) * core.Height() / grid;
      const double h = surface_height_m(east, north);
      points.emplace_back(east, north, std::isfinite(h) ? h : fallback_height_m);
    }
  }
  return points;
}

std::vector<OrbitView> OrbitRing(const Eigen::Vector3d& look_at, double radius_m, double elevation_deg, int count,
                                 double azimuth0_deg, double fov_deg, int width_px, int height_px) {
  std::vector<OrbitView> ring;
  const double el = elevation_deg * M_PI / 180.0;
  for (int k = 0; k < count; ++k) {
    OrbitView v;
    v.view = k;
    v.elevation_deg = elevation_deg;
    v.azimuth_deg = std::fmod(azimuth0_deg + 360.0 * k / count, 360.0);
    v.radius_m = radius_m;
    v.look_at_enu_m = look_at;
    const double az = v.azimuth_deg * M_PI / 180.0;  // clockwise from north: east = sin, north = cos
    const Eigen::Vector3d eye =
        look_at + radius_m * Eigen::Vector3d(std::cos(el) * std::sin(az), std::cos(el) * std::cos(az), std::sin(el));
    v.camera = LookAtCamera(eye, look_at, fov_deg, width_px, height_px);
    ring.push_back(v);
  }
  return ring;
}

std::vector<OrbitView> EpisodeViews(const OrbitOptions& o, const GroundBox& core,
                                    const std::vector<Eigen::Vector3d>& look_at, int episode) {
  std::vector<OrbitView> views;
  const double elevation = EpisodeElevationDeg(o, episode), radius = EpisodeRadiusM(o, core, episode);
  for (std::size_t p = 0; p < look_at.size(); ++p) {
    // Golden-ratio phases: every point and episode starts its ring elsewhere.
    const double phase = std::fmod(0.6180339887 * static_cast<double>(episode * look_at.size() + p), 1.0);
    for (OrbitView& v : OrbitRing(look_at[p], radius, elevation, o.views_per_point, phase * 360.0 / o.views_per_point,
                                  o.fov_deg, o.width_px, o.height_px)) {
      v.episode = episode;
      v.point = static_cast<int>(p);
      v.name = "e" + std::to_string(episode) + "_p" + std::to_string(p) + "_v" + std::to_string(v.view);
      views.push_back(std::move(v));
    }
  }
  return views;
}

std::string OrbitCamerasJson(const std::vector<OrbitView>& views, const GeodeticPoint& origin) {
  using json = nlohmann::json;
  auto matrix = [](const Eigen::Matrix3d& m) {
    return json{{m(0, 0), m(0, 1), m(0, 2)}, {m(1, 0), m(1, 1), m(1, 2)}, {m(2, 0), m(2, 1), m(2, 2)}};
  };
  auto vector = [](const Eigen::Vector3d& v) { return json{v.x(), v.y(), v.z()}; };
  json images = json::array();
  for (const OrbitView& v : views) {
    images.push_back({{"name", v.name},
                      {"used", true},
                      {"split", "train"},
                      {"width_px", v.camera.width_px},
                      {"height_px", v.camera.height_px},
                      {"K", matrix(v.camera.K())},
                      {"R", matrix(v.camera.cam_from_world_rotation)},
                      {"t", vector(v.camera.cam_from_world_translation)},
                      {"centre_enu_m", vector(v.camera.Centre())},
                      {"episode", v.episode},
                      {"elevation_deg", v.elevation_deg},
                      {"azimuth_deg", v.azimuth_deg},
                      {"radius_m", v.radius_m},
                      {"look_at_enu_m", vector(v.look_at_enu_m)}});
  }
  const json doc = {{"schema", "skyfall.cameras/1"},
                    {"frame", {{"type", "enu"},
                               {"origin", {{"lon_deg", origin.lon_deg}, {"lat_deg", origin.lat_deg},
                                           {"height_m", origin.height_m}}}}},
                    {"conventions", "x_cam = R * X_enu + t; pixel = K * x_cam / z; top-left pixel centre at (0, 0)"},
                    {"images", images}};
  return doc.dump(2) + "\n";
}

}  // namespace skyfall
