// Satellite views of a synthetic city: a pinhole camera in the city's ENU
// frame and a ray caster over the height field, so buildings hide what is
// behind them and cast shadows for each date's sun.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "testcity/city.h"

namespace skyfall::synth {

// Pinhole camera, pixel centres at integer coordinates (the RPC00B
// convention). ENU metres; the centre is ~650 km away, so everything is double.
struct SatelliteCamera {
  Eigen::Matrix3d cam_from_enu = Eigen::Matrix3d::Identity();  // rows: right, down, forward
  Eigen::Vector3d centre_enu_m = Eigen::Vector3d::Zero();
  double focal_px = 1.0;
  Eigen::Vector2d principal_px = Eigen::Vector2d::Zero();
  int width_px = 0;
  int height_px = 0;

  Eigen::Vector2d Project(const Eigen::Vector3d& enu_m) const;
  Eigen::Vector3d RayDirectionEnu(double col, double row) const;  // unit vector
};

// Affine map ENU -> scene frame, fitted over the city. The true map (ENU ->
// geodetic -> UTM) bends by a few millimetres over a few hundred metres;
// `max_error_m` reports how far the affine map is from it on the fit grid.
struct SceneFromEnu {
  Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();
  Eigen::Vector3d offset_m = Eigen::Vector3d::Zero();
  double max_error_m = 0.0;
  Eigen::Vector3d Apply(const Eigen::Vector3d& enu_m) const { return linear * enu_m + offset_m; }
};

// One cumulus puff of a cloud layer: a disc of the layer, opaque at its
// centre and fading to nothing at its edge. Scene frame [m].
struct CloudPuff {
  Eigen::Vector2d centre_m = Eigen::Vector2d::Zero();
  double radius_m = 100.0;
};

// A layer of cumulus at one height over the city: what a satellite sees
// instead of the ground where its ray crosses a puff, and the shadows the
// puffs cast where the sun's ray crosses one. Empty: a clear sky.
struct CloudLayer {
  double height_m = 0.0;          // scene z (ellipsoidal) of the layer
  std::vector<CloudPuff> puffs;
  // Opacity of the layer at scene (x, y): each puff's (1 - (d/r)^2)^2,
  // summed and capped at 1.
  float OpacityAt(double x_m, double y_m) const;
  // Opacity where the ray from `from` along `direction` (scene frame)
  // crosses the layer, forwards or backwards; 0 for a horizontal ray.
  float OpacityAlong(const Eigen::Vector3d& from, const Eigen::Vector3d& direction) const;
};

struct Lighting {
  Eigen::Vector3d sun_scene = Eigen::Vector3d::UnitZ();  // unit vector towards the sun, scene frame
  float ambient = 0.35f;                                  // sky light share
  float gain = 1.0f;                                      // sensor gain of the date
  Eigen::Vector3f tint = Eigen::Vector3f::Ones();         // atmosphere colour cast
  // Path radiance: the share of each pixel's light that the haze between
  // the ground and the sensor adds, the same bright blue-grey everywhere.
  // It lowers contrast and pulls every colour towards grey, as a hazy
  // satellite image's crowns are barely greener than its roofs.
  float haze = 0.0f;
  // Clouds of the date (cloudy dates of `skyfall synth --clouds`): they hide
  // the ground in the view and shade it from the sun. The true orthophoto
  // is drawn without them.
  CloudLayer clouds;
  std::uint64_t noise_seed = 0;                           // sensor noise pattern
  float noise_dn = 0.0f;  // Gaussian sensor noise [DN, 8-bit scale], beside the +-1 DN always there
  float blur_px = 0.0f;   // the optics' Gaussian point-spread function, standard deviation [px]; 0 none
  bool cast_shadows = true;                               // off only to test shadowing
  // A detector integrates the light over its pixel. Point-sampled at the
  // pixel's centre, textures finer than two pixels (tile courses, road
  // markings) alias into a moire that differs in every view and correlates
  // between none; the texture is averaged over `subpixels` x `subpixels`
  // points of the pixel's footprint instead (1: point sampling). Shading and
  // shadows are the centre's.
  int subpixels = 4;
};

struct RenderedView {
  int width_px = 0;
  int height_px = 0;
  std::vector<std::uint8_t> rgb;        // interleaved, row-major
  std::vector<Eigen::Vector3f> hit_scene;  // surface point seen by each pixel (NaN if none)
  std::vector<std::int32_t> hit_object;    // building index, -1 otherwise
  double cloud_covered_fraction = 0.0;     // share of pixels whose ray crosses clouds of opacity >= 0.5
};

RenderedView RenderView(const City& city, const SatelliteCamera& camera,
                        const SceneFromEnu& scene_from_enu, const Lighting& lighting);

// The city's true orthophoto on a north-up grid of the scene frame (the
// north-west corner at (x0_m, y_top_m), `gsd_m` pixels): what a vertical ray
// through each pixel sees, lit and coloured like a view under `lighting`,
// without the sensor's noise. RGB, interleaved, row 0 the north edge.
std::vector<std::uint8_t> RenderOrtho(const City& city, const Lighting& lighting, double x0_m, double y_top_m,
                                      double gsd_m, int width_px, int height_px);

}  // namespace skyfall::synth
