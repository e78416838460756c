#include "core/pinhole.h"

#include <gtest/gtest.h>

#include <random>

namespace skyfall {
namespace {

// Back-projecting a projected point with its depth gives the point back.
// Tolerance: a satellite-like camera 6e5 m away with f = 2e6 px; doubles
// carry ~1e-16 relative, so 1e-6 m after the 6e5 m lever is ample margin
// while any wrong term (a missing skew, a transposed R) is off by metres.
TEST(PinholeCamera, PixelToWorldUndoesProjection) {
  constexpr double kPointTolM = 1e-6;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  PinholeCamera near = LookAtCamera({120.0, -80.0, 90.0}, {0.0, 0.0, 10.0}, 60.0, 640, 480);
  PinholeCamera far = LookAtCamera({2.0e5, 1.0e5, 5.5e5}, {0.0, 0.0, 0.0}, 0.02, 2048, 2048);
  far.skew = 3.5;
  far.fy *= 1.01;
  for (const PinholeCamera& cam : {near, far}) {
    const PixelToWorld to_world(cam);
    for (int i = 0; i < 100; ++i) {
      const Eigen::Vector3d X(u(rng), u(rng), 0.3 * u(rng));
      const Eigen::Vector2d uv = cam.Project(X);
      const Eigen::Vector3d back = to_world(uv.x(), uv.y(), cam.Depth(X));
      EXPECT_LT((back - X).norm(), kPointTolM) << i;
    }
  }
}

// The footprint of one pixel: a nadir camera 600 km up whose focal length
// makes 0.5 m pixels at the ground, checked against the distance between the
// ground points of two neighbouring pixels; nothing is seen behind it.
TEST(PinholeCamera, PixelFootprintIsTheGroundDistanceBetweenNeighbouringPixels) {
  constexpr double kAltitudeM = 6.0e5, kGsdM = 0.5;
  // One metre off the vertical (LookAtCamera needs a direction to roll by).
  PinholeCamera nadir = LookAtCamera({0.0, -1.0, kAltitudeM}, {0.0, 0.0, 0.0}, 1.0, 1000, 1000);
  nadir.fx = nadir.fy = kAltitudeM / kGsdM;
  const PixelToWorld to_world(nadir);
  const Eigen::Vector3d ground(0.0, 0.0, 0.0);
  const Eigen::Vector2d uv = nadir.Project(ground);
  const double depth_m = nadir.Depth(ground);
  const double step_m = (to_world(uv.x() + 1, uv.y(), depth_m) - to_world(uv.x(), uv.y(), depth_m)).norm();
  // Doubles after a 6e5 m lever: 1e-9 m is far below any wrong factor.
  EXPECT_NEAR(nadir.PixelFootprintM(ground), kGsdM, 1e-9);
  EXPECT_NEAR(step_m, kGsdM, 1e-9);
  EXPECT_TRUE(std::isinf(nadir.PixelFootprintM({0.0, -2.0, 2 * kAltitudeM})));
}

}  // namespace
}  // namespace skyfall
