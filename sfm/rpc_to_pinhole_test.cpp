#include "sfm/rpc_to_pinhole.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <limits>

#include "testcity/testcity.h"
#include "tests/test_support.h"
#include "ingest/geo.h"
#include "ingest/raster.h"
#include "ingest/rpc_io.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

// The target for the pinhole approximation of each JAX_068 crop.
constexpr double kPinholeMaxErrorPx = 0.05;

auto EnuFunction(const EnuFrame& frame) {
  return [frame](const GeodeticPoint& g) { return frame.EnuFromGeodetic(g); };
}

TEST(RpcToPinhole, RecoversTheTrueCamerasOfTheSyntheticScene) {
  synth::SynthOptions o;
  o.size_m = 128;
  o.views = 4;
  NullProgress progress;
  const fs::path root = ScratchDir("synth");
  const synth::SynthResult scene = synth::RunSynth(o, root.string(), progress);
  const EnuFrame frame(scene.enu_origin);
  for (const synth::SynthView& v : scene.aois.at(0).views) {
    const RpcModel rpc = ReadRpcFromRaster(v.path);
    const PinholeFit fit = ApproximateRpcByPinhole(rpc, v.camera.width_px, v.camera.height_px,
                                                   EllipsoidHeightM(scene.city.min_height_m),
                                                   EllipsoidHeightM(scene.city.max_height_m),
                                                   EnuFunction(frame));
    // The RPC was fitted to a perspective camera, so a pinhole reproduces it
    // to the RPC fit's own residual (~1e-8 px).
    EXPECT_LT(fit.max_error_px, 1e-4) << v.name;
    const PinholeCamera& cam = fit.camera;
    // Geometry: the focal length and range trade off along the line of sight
    // (a 0.01% change in both moves pixels by ~1e-4 px over a 100 m scene),
    // so they are compared relatively; the viewing direction is tight.
    EXPECT_NEAR(cam.fx / v.camera.focal_px, 1.0, 1e-3) << v.name;
    EXPECT_NEAR(cam.fy / v.camera.focal_px, 1.0, 1e-3) << v.name;
    EXPECT_LT(std::abs(cam.skew), 1.0) << v.name;
    const Eigen::Vector3d true_axis = v.camera.cam_from_enu.row(2).transpose();
    const Eigen::Vector3d axis = cam.cam_from_world_rotation.row(2).transpose();
    EXPECT_LT(std::acos(std::min(1.0, axis.dot(true_axis))), 1e-5) << v.name;  // ~2 arcsec
    EXPECT_LT((cam.Centre() - v.camera.centre_enu_m).norm() / (v.range_km * 1000.0), 1e-3) << v.name;
    EXPECT_NEAR(cam.cx, v.camera.principal_px.x(), 0.02 * v.camera.width_px) << v.name;
  }
}

TEST(RpcToPinhole, Jax068CropsWithinTarget) {
  SKYFALL_REQUIRE_DFC2019();
  // The AOI frame and height range as ingest computes them for JAX_068.
  const EnuFrame frame({-81.66375220653791, 30.34880946879006, 1.46});
  double worst = 0, sum_max = 0, worst_dlt = 0;
  int n = 0;
  for (const auto& e : fs::directory_iterator(Dfc2019Root() / "Track3-RGB-crops" / "JAX_068")) {
    const RasterInfo info = ReadRasterInfo(e.path().string());
    const PinholeFit fit = ApproximateRpcByPinhole(ReadRpcFromRaster(e.path().string()), info.width_px,
                                                   info.height_px, EllipsoidHeightM(-31.3), EllipsoidHeightM(34.2),
                                                   EnuFunction(frame));
    EXPECT_LE(fit.max_error_px, kPinholeMaxErrorPx) << e.path();
    std::printf("  %s: DLT max %.4f mean %.4f -> refined max %.4f mean %.4f, skew %.3g px\n",
                e.path().filename().c_str(), fit.dlt_max_error_px, fit.dlt_mean_error_px,
                fit.max_error_px, fit.mean_error_px, fit.camera.skew);
    worst = std::max(worst, fit.max_error_px);
    worst_dlt = std::max(worst_dlt, fit.dlt_max_error_px);
    sum_max += fit.max_error_px;
    ++n;
  }
  EXPECT_EQ(n, 19);
  std::printf("[figures] JAX_068 RPC->pinhole: max error %.4f px, average of per-image max %.4f px, "
              "DLT alone max %.4f px\n", worst, sum_max / n, worst_dlt);
}

TEST(RpcToPinhole, StiffCameraNeedsHartleyNormalization) {
  SKYFALL_REQUIRE_DFC2019();
  // The stiff case: f ~ 2e6 px with the camera ~6e5 m away, here in a frame
  // whose origin is as far as UTM's (1e5-1e6 m), the trap DESIGN.md warns of.
  const EnuFrame frame({-81.66375220653791, 30.34880946879006, 1.46});
  const Eigen::Vector3d far_origin(436000.0, 3357000.0, 0.0);
  auto far_frame = [&](const GeodeticPoint& g) { return Eigen::Vector3d(frame.EnuFromGeodetic(g) + far_origin); };
  const fs::path image = Jax068Image("010");  // the most oblique crop
  const RasterInfo info = ReadRasterInfo(image.string());
  const RpcModel rpc = ReadRpcFromRaster(image.string());
  PinholeFitOptions raw;
  raw.hartley_normalization = false;
  raw.refine = false;
  PinholeFitOptions normalized = raw;
  normalized.hartley_normalization = true;
  const PinholeFit b = ApproximateRpcByPinhole(rpc, info.width_px, info.height_px, EllipsoidHeightM(-31.3), EllipsoidHeightM(34.2),
                                               far_frame, normalized);
  EXPECT_LT(b.dlt_max_error_px, kPinholeMaxErrorPx);
  // Losing the normalization must show: either the decomposition is refused
  // (a camera facing away) or the camera is off by pixels.
  double raw_error_px = std::numeric_limits<double>::infinity();
  try {
    raw_error_px = ApproximateRpcByPinhole(rpc, info.width_px, info.height_px, EllipsoidHeightM(-31.3),
                                           EllipsoidHeightM(34.2), far_frame, raw)
                       .dlt_max_error_px;
  } catch (const Error& e) {
    std::printf("[figures] stiff DLT without normalization: %s\n", e.what());
  }
  std::printf("[figures] stiff DLT in a UTM-sized frame: without normalization %.3g px, with %.3g px\n",
              raw_error_px, b.dlt_max_error_px);
  EXPECT_GT(raw_error_px, 1.0);
}

TEST(RpcToPinhole, RejectsAnEmptyHeightRange) {
  SKYFALL_REQUIRE_DFC2019();
  const RpcModel rpc = ReadRpcFromRaster(Jax068Image("001").string());
  const EnuFrame frame({-81.66, 30.35, 0});
  EXPECT_THROW(ApproximateRpcByPinhole(rpc, 100, 100, EllipsoidHeightM(5.0), EllipsoidHeightM(5.0), EnuFunction(frame)), Error);
}

}  // namespace
}  // namespace skyfall
