#include "core/rpc_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "core/error.h"
#include "tests/test_rpc_fixture.h"

namespace skyfall {
namespace {

// The synthetic-scene requirement: a fitted RPC reproduces its camera within
// 0.01 px.
constexpr double kFitTolPx = 0.01;

TEST(RpcFit, RecoversAnRpcExactly) {
  const RpcModel truth = testing::MakeTestRpc();
  const RpcFitDomain domain{truth.lon_off - 0.01, truth.lon_off + 0.01, truth.lat_off - 0.01,
                            truth.lat_off + 0.01, -50.0, 100.0};
  const RpcFitResult fit = FitRpc(
      [&](double lon, double lat, double h) { return truth.Project(lon, lat, h); }, domain);
  EXPECT_LT(fit.max_residual_px, 1e-4);
}

TEST(RpcFit, FitsAPerspectiveSatelliteCameraWithinAHundredthOfAPixel) {
  // A WorldView-3-like frame camera 650 km away, 30 deg off nadir, 0.5 m GSD.
  const double lon0 = -81.66, lat0 = 30.35;
  const double m_per_deg_lat = 110574.0, m_per_deg_lon = 111320.0 * std::cos(lat0 * M_PI / 180);
  const double range_m = 650e3, focal_px = range_m / 0.5;
  const double zenith = 30.0 * M_PI / 180, azimuth = 40.0 * M_PI / 180;
  const Eigen::Vector3d centre = range_m * Eigen::Vector3d(std::sin(zenith) * std::sin(azimuth),
                                                           std::sin(zenith) * std::cos(azimuth),
                                                           std::cos(zenith));
  const Eigen::Vector3d forward = -centre.normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitY()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  auto project = [&](double lon, double lat, double h) {
    // Local metric coordinates with a curvature term, so the map is not a
    // plain rational function of (lon, lat, h).
    const double x = (lon - lon0) * m_per_deg_lon, y = (lat - lat0) * m_per_deg_lat;
    const Eigen::Vector3d p(x, y, h - (x * x + y * y) / (2 * 6.371e6));
    const Eigen::Vector3d v = p - centre;
    const double z = v.dot(forward);
    return Eigen::Vector2d(focal_px * v.dot(right) / z + 300.0, focal_px * v.dot(down) / z + 280.0);
  };
  const double half = 200.0;  // 400 m square
  const RpcFitDomain domain{lon0 - half / m_per_deg_lon, lon0 + half / m_per_deg_lon,
                            lat0 - half / m_per_deg_lat, lat0 + half / m_per_deg_lat, -40.0, 110.0};
  const RpcFitResult fit = FitRpc(project, domain);
  EXPECT_LT(fit.max_residual_px, kFitTolPx);
  EXPECT_LE(fit.rms_residual_px, fit.max_residual_px);
  std::printf("[figures] perspective camera fit: max %.3g px, rms %.3g px, rational %d\n",
              fit.max_residual_px, fit.rms_residual_px, fit.rational);
  // And the fitted model evaluates where the camera does at the scene centre.
  EXPECT_LT((fit.rpc.Project(lon0, lat0, 0.0) - project(lon0, lat0, 0.0)).norm(), kFitTolPx);
}

TEST(RpcFit, RejectsAnEmptyDomainAndBadOptions) {
  const RpcModel truth = testing::MakeTestRpc();
  auto f = [&](double lon, double lat, double h) { return truth.Project(lon, lat, h); };
  EXPECT_THROW(FitRpc(f, {1, 1, 0, 1, 0, 1}), Error);
  RpcFitOptions bad;
  bad.fit_steps_height = 2;
  EXPECT_THROW(FitRpc(f, {-81.7, -81.6, 30.2, 30.3, 0, 10}, bad), Error);
}

}  // namespace
}  // namespace skyfall
