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

}  // namespace
}  // namespace skyfall
