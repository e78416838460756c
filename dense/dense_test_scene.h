// Scenes for the dense sweep's tests and benchmark: satellite-like pinhole
// views of textured ground with a raised square plateau, drawn exactly.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "core/pinhole.h"
#include "dense/dense.h"

namespace skyfall::testing {

// A camera 600 km from the origin looking at it, at `zenith_deg` from the
// vertical towards azimuth `azimuth_deg`, with `size_px` square pixels of
// `gsd_m` at the ground.
inline PinholeCamera LookingDown(double zenith_deg, double azimuth_deg, int size_px = 128, double gsd_m = 0.5) {
  const double z = zenith_deg * M_PI / 180, a = azimuth_deg * M_PI / 180;
  const Eigen::Vector3d centre = 6e5 * Eigen::Vector3d(std::sin(z) * std::sin(a), std::sin(z) * std::cos(a), std::cos(z));
  const Eigen::Vector3d forward = -centre.normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized().eval();
  const Eigen::Vector3d right_or_east = right.norm() > 0.5 ? right : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d down = forward.cross(right_or_east);
  PinholeCamera c;
  c.cam_from_world_rotation.row(0) = right_or_east;
  c.cam_from_world_rotation.row(1) = down;
  c.cam_from_world_rotation.row(2) = forward;
  c.cam_from_world_translation = -c.cam_from_world_rotation * centre;
  c.fx = c.fy = 6e5 / gsd_m;
  c.cx = c.cy = 0.5 * (size_px - 1);
  c.width_px = c.height_px = size_px;
  return c;
}

// Value noise on a 1 m lattice, bilinear between lattice points: texture
// without repeats, so each height has one best match. Grey levels 50-200.
inline float GroundTexture(double x_m, double y_m) {
  auto lattice = [](long i, long j) {
    std::uint32_t h = static_cast<std::uint32_t>(i * 73856093L ^ j * 19349663L);
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return static_cast<float>(h % 1000u) / 1000.0f;
  };
  const double fx = std::floor(x_m), fy = std::floor(y_m);
  const long i = static_cast<long>(fx), j = static_cast<long>(fy);
  const float u = static_cast<float>(x_m - fx), v = static_cast<float>(y_m - fy);
  const float top = lattice(i, j) + u * (lattice(i + 1, j) - lattice(i, j));
  const float bottom = lattice(i, j + 1) + u * (lattice(i + 1, j + 1) - lattice(i, j + 1));
  return 50.0f + 150.0f * (top + v * (bottom - top));
}

// A one-band view of the camera's size, every pixel `grey`.
inline DenseView UniformView(const std::string& name, const PinholeCamera& camera, float grey) {
  DenseView v;
  v.name = name;
  v.camera = camera;
  v.width_px = camera.width_px;
  v.height_px = camera.height_px;
  v.bands = 1;
  v.pixels.assign(static_cast<std::size_t>(v.width_px) * v.height_px, grey);
  return v;
}

// A one-band view of textured ground at 0 m with a square plateau of
// half-side `plateau_half_m` at `plateau_m` (its walls are not drawn: what
// matters is texture at two heights), the plateau's texture
// `plateau_texture` (the ground's by default).
inline DenseView TexturedView(const std::string& name, const PinholeCamera& camera, double plateau_m,
                              double plateau_half_m, float (*plateau_texture)(double, double) = GroundTexture) {
  DenseView v = UniformView(name, camera, 0.0f);
  const Eigen::Vector3d centre = camera.Centre();
  const Eigen::Matrix3d world_from_cam = camera.cam_from_world_rotation.transpose();
  for (int row = 0; row < v.height_px; ++row)
    for (int col = 0; col < v.width_px; ++col) {
      const Eigen::Vector3d ray =
          world_from_cam * Eigen::Vector3d((col - camera.cx) / camera.fx, (row - camera.cy) / camera.fy, 1.0);
      const Eigen::Vector3d top = centre + ray * ((plateau_m - centre.z()) / ray.z());
      const bool on_plateau = std::abs(top.x()) <= plateau_half_m && std::abs(top.y()) <= plateau_half_m;
      const Eigen::Vector3d hit = on_plateau ? top : Eigen::Vector3d(centre + ray * (-centre.z() / ray.z()));
      v.pixels[static_cast<std::size_t>(row) * v.width_px + col] =
          on_plateau ? plateau_texture(hit.x(), hit.y()) : GroundTexture(hit.x(), hit.y());
    }
  return v;
}

// One band view of two buildings (boxes with textured roofs and walls)
// either side of a narrow street running north-south, on textured ground:
// rays stop at the first roof, wall or ground they meet.
inline DenseView TwoBuildingsView(const std::string& name, const PinholeCamera& camera, double street_half_m,
                           double building_m) {
  DenseView v = UniformView(name, camera, 0.0f);
  const Eigen::Vector3d centre = camera.Centre();
  const Eigen::Matrix3d world_from_cam = camera.cam_from_world_rotation.transpose();
  const double boxes[2][4] = {{-street_half_m - 12, -12, -street_half_m, 12}, {street_half_m, -12, street_half_m + 12, 12}};
  for (int row = 0; row < v.height_px; ++row)
    for (int col = 0; col < v.width_px; ++col) {
      const Eigen::Vector3d ray =
          world_from_cam * Eigen::Vector3d((col - camera.cx) / camera.fx, (row - camera.cy) / camera.fy, 1.0);
      double t_hit = -centre.z() / ray.z();  // the ground
      int face = 0;                          // 0 ground, 1 roof, 2 wall
      for (const auto& b : boxes) {
        // Slab intersection with the box [b0, b2] x [b1, b3] x [0, building_m].
        double t0 = 0, t1 = std::numeric_limits<double>::infinity();
        int entry_axis = -1;
        const double lo[3] = {b[0], b[1], 0.0}, hi[3] = {b[2], b[3], building_m};
        bool miss = false;
        for (int a = 0; a < 3 && !miss; ++a) {
          double ta = (lo[a] - centre[a]) / ray[a], tb = (hi[a] - centre[a]) / ray[a];
          if (ta > tb) std::swap(ta, tb);
          if (ta > t0) {
            t0 = ta;
            entry_axis = a;
          }
          t1 = std::min(t1, tb);
          miss = t0 > t1;
        }
        if (!miss && t0 < t_hit) {
          t_hit = t0;
          face = entry_axis == 2 ? 1 : 2;
        }
      }
      const Eigen::Vector3d p = centre + t_hit * ray;
      float grey = GroundTexture(p.x(), p.y());
      if (face == 1) grey = 0.8f * GroundTexture(p.x() + 50.0, p.y() - 40.0) + 40.0f;
      if (face == 2) grey = 0.5f * GroundTexture(p.x() + p.y(), p.z()) + 20.0f;
      v.pixels[static_cast<std::size_t>(row) * v.width_px + col] = grey;
    }
  return v;
}

// Two 20 m buildings either side of a 4 m north-south street, seen by six
// views (nadir, along the street and across it), every pair matched, and
// tie points at the ground's corners and on a roof.
struct StreetScene {
  static constexpr double kStreetHalfM = 2.0, kBuildingM = 20.0;
  std::vector<DenseView> views;
  std::vector<DensePair> pairs;
  std::vector<Eigen::Vector3d> points = {{-25, -25, 0}, {25, -25, 0}, {-25, 25, 0}, {25, 25, 0}, {-8, 0, kBuildingM}};
};
inline StreetScene StreetBetweenTwoBuildings() {
  StreetScene s;
  const double zenith_deg[] = {0, 12, 18, 22, 15, 10}, azimuth_deg[] = {0, 90, 270, 0, 180, 180};
  for (int v = 0; v < 6; ++v)
    s.views.push_back(TwoBuildingsView("v" + std::to_string(v), LookingDown(zenith_deg[v], azimuth_deg[v], 128),
                                       StreetScene::kStreetHalfM, StreetScene::kBuildingM));
  for (int a = 0; a < 6; ++a)
    for (int b = a + 1; b < 6; ++b) s.pairs.push_back({a, b, 100});
  return s;
}

}  // namespace skyfall::testing
