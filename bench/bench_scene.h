// The benchmarks' reference scene: 100k Gaussians on a 100 m x 100 m
// city-like surface seen by an oblique 512x384 camera (the size the speed
// targets are stated for).
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "core/gaussians.h"
#include "core/pinhole.h"

namespace skyfall {

constexpr int kWidth = 512, kHeight = 384;

// An oblique orbit-style camera 120 m from the scene centre, 60 deg FOV,
// at `azimuth_deg` around the vertical axis (0: looking north).
inline PinholeCamera BenchCamera(double azimuth_deg) {
  PinholeCamera cam;
  cam.fx = cam.fy = 0.5 * kWidth / std::tan(30.0 * M_PI / 180.0);
  cam.cx = 0.5 * (kWidth - 1);
  cam.cy = 0.5 * (kHeight - 1);
  cam.width_px = kWidth;
  cam.height_px = kHeight;
  const double a = azimuth_deg * M_PI / 180.0;
  const Eigen::Vector3d centre(70 * std::sin(a), -70 * std::cos(a), 100), target(0, 0, 0);
  const Eigen::Vector3d f = (target - centre).normalized();
  const Eigen::Vector3d r = f.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d d = f.cross(r);
  cam.cam_from_world_rotation.row(0) = r.transpose();
  cam.cam_from_world_rotation.row(1) = d.transpose();
  cam.cam_from_world_rotation.row(2) = f.transpose();
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * centre;
  return cam;
}

// `n` Gaussians ~0.3 m in size on blocks 10 m tall: what a trained tile
// looks like.
inline GaussianCloud BenchCloud(int n, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  GaussianCloud c;
  c.resize(n);
  for (int i = 0; i < n; ++i) {
    const float x = 50 * u(rng), y = 50 * u(rng);
    c.means[i] = Eigen::Vector3f(x, y, 10.0f * (std::sin(x * 0.2f) > 0.3f ? 1.0f : 0.0f) + 0.2f * u(rng));
    c.log_scales[i] = Eigen::Vector3f::Constant(std::log(0.3f)) + 0.3f * Eigen::Vector3f(u(rng), u(rng), u(rng));
    c.rotations[i] = Eigen::Vector4f(1, 0.3f * u(rng), 0.3f * u(rng), 0.3f * u(rng));
    c.opacity_logits[i] = 1.0f + u(rng);
    for (auto& v : c.sh[i]) v = 0.3f * u(rng);
  }
  return c;
}

}  // namespace skyfall
