// Orbit cameras of the synthesis stage (Skyfall-GS Sec. 3.2, Algorithm 1):
// N_p look-at points on a grid over a tile's core at the surface height,
// N_v perspective views per point on a circle around it, at an elevation
// and radius that fall from episode to episode (the curriculum: high views
// first, where the satellite-trained scene renders well).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/option_range.h"
#include "core/pinhole.h"
#include "core/tile.h"

namespace skyfall {

struct OrbitOptions {
  int grid = 3;                        // N_p = grid x grid look-at points (paper: 3 x 3)
  int views_per_point = 6;             // N_v (paper: 6)
  int episodes = 3;                    // N_e (paper: 5; fewer on a CPU, decision D-130)
  double elevation_start_deg = 85.0;   // first episode (paper: 85 -> 45)
  double elevation_end_deg = 45.0;     // last episode
  // Orbit radius as a multiple of the core's side, first and last episode.
  // The paper's DFC2019 setting is 300 -> 250 units around a 3 x 3 grid 512
  // units wide; the same proportions are 0.59 -> 0.49 of the grid's side.
  double radius_start_per_core = 0.59;
  double radius_end_per_core = 0.49;
  // [m] radius floor: keeps the cameras of small tiles above the rooftops
  // (at 45 deg, 106 m above the look-at point), where the scene is seen from
  // outside rather than from within the Gaussians of a tower.
  double min_radius_m = 150.0;
  // The paper gives no field of view for the orbit views; 60 deg (as for
  // the pseudo cameras) sees the neighbouring look-at points at the start
  // radius, so consecutive points' views overlap.
  double fov_deg = 60.0;
  int width_px = 256;                  // the paper renders 2048 x 2048 on a GPU
  int height_px = 256;
  void Check() const;                  // throws Error("idu", field, ...)
};
template <class IO> void Visit(IO& io, OrbitOptions& o) {
  io("grid", o.grid,
     "The look-at points form a grid x grid square over the tile's core", range::In(1, 16));
  io("views_per_point", o.views_per_point,
     "Orbit views per look-at point in each episode", range::In(1, 64));
  io("episodes", o.episodes,
     "Episodes of the curriculum, from high to low elevation", range::In(1, 50));
  io("elevation_start_deg", o.elevation_start_deg,
     "Elevation of the orbit views in the first episode", range::Inside(5, 90));
  io("elevation_end_deg", o.elevation_end_deg,
     "Elevation of the orbit views in the last episode", range::Inside(5, 90));
  io("radius_start_per_core", o.radius_start_per_core,
     "Orbit radius in the first episode, as a multiple of the core's side", range::AboveUpTo(0, 10));
  io("radius_end_per_core", o.radius_end_per_core,
     "Orbit radius in the last episode, as a multiple of the core's side", range::AboveUpTo(0, 10));
  io("min_radius_m", o.min_radius_m,
     "Smallest orbit radius, which keeps the cameras of small tiles above the rooftops", range::AtLeast(0));
  io("fov_deg", o.fov_deg,
     "Field of view of the orbit views", range::In(5, 120));
  io("width_px", o.width_px,
     "Width of an orbit view", range::In(16, 4096));
  io("height_px", o.height_px,
     "Height of an orbit view", range::In(16, 4096));
}

// One orbit view of one episode.
struct OrbitView {
  std::string name;                    // "e<episode>_p<point>_v<view>"
  PinholeCamera camera;
  int episode = 0, point = 0, view = 0;
  double elevation_deg = 0, azimuth_deg = 0, radius_m = 0;  // azimuth clockwise from north
  Eigen::Vector3d look_at_enu_m = Eigen::Vector3d::Zero();
};

// Elevation and radius of episode `episode` (0-based), falling linearly.
double EpisodeElevationDeg(const OrbitOptions& options, int episode);
double EpisodeRadiusM(const OrbitOptions& options, const GroundBox& core, int episode);

// grid x grid points at the centres of the core's cells, at the height
// `surface_height_m(east, north)` returns (NaN there: `fallback_height_m`).
std::vector<Eigen::Vector3d> LookAtGrid(const GroundBox& core, int grid,
                                        const std::function<double(double, double)>& surface_height_m,
                                        double fallback_height_m);

// `count` views at equal azimuth steps around `look_at`, the first at
// `azimuth0_deg`, `radius_m` away at `elevation_deg`.
std::vector<OrbitView> OrbitRing(const Eigen::Vector3d& look_at, double radius_m, double elevation_deg, int count,
                                 double azimuth0_deg, double fov_deg, int width_px, int height_px);

// Every view of one episode: N_v per look-at point; the ring of each point
// turns by a different phase in each episode, so the episodes see the
// facades from different sides.
std::vector<OrbitView> EpisodeViews(const OrbitOptions& options, const GroundBox& core,
                                    const std::vector<Eigen::Vector3d>& look_at, int episode);

// A cameras.json (schema skyfall.cameras/1, frame ENU at `origin`) of the
// views, readable by ReadCameraEntries and `skyfall splat render`, with each
// view's elevation, azimuth, radius and look-at point.
std::string OrbitCamerasJson(const std::vector<OrbitView>& views, const GeodeticPoint& origin);

}  // namespace skyfall
