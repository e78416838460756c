// A tile: one independent unit of reconstruction work. Tiles of one city
// share one ENU frame; their core boxes partition the city's ground plane and
// each tile is reconstructed over its core plus an overlap margin, so that the
// merge can stitch neighbours without seams.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/aoi.h"

namespace skyfall {

// Axis-aligned box on the ENU ground plane [m].
struct GroundBox {
  Eigen::Vector2d min_m = Eigen::Vector2d::Zero();  // (east, north)
  Eigen::Vector2d max_m = Eigen::Vector2d::Zero();
  double Width() const { return max_m.x() - min_m.x(); }
  double Height() const { return max_m.y() - min_m.y(); }
  bool Contains(double east_m, double north_m) const {
    return east_m >= min_m.x() && east_m < max_m.x() && north_m >= min_m.y() && north_m < max_m.y();
  }
};

// The regular grid of tile cores over a city. Cores are half-open boxes of
// tile_m x tile_m starting at `origin_m`; the outermost cores extend to
// infinity for ownership, so every ground point has exactly one owner.
struct TileGrid {
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();  // lower-left corner of core (0, 0)
  double tile_m = 256.0;
  double overlap_m = 8.0;
  int cols = 0;  // along east
  int rows = 0;  // along north

  GroundBox Core(int col, int row) const {
    GroundBox b;
    b.min_m = origin_m + Eigen::Vector2d(col * tile_m, row * tile_m);
    b.max_m = b.min_m + Eigen::Vector2d(tile_m, tile_m);
    return b;
  }
  // (col, row) of the tile whose core owns a ground point (clamped at the edges).
  Eigen::Vector2i Owner(double east_m, double north_m) const;
};

// One image of a tile: a crop window of a source image and its RPC for the
// crop's pixel grid.
struct TileImage {
  std::string name;
  std::string source_path;  // the full image
  std::string crop_path;    // GDAL VRT referencing the window (no pixel copy)
  int col0_px = 0, row0_px = 0, width_px = 0, height_px = 0;  // window in the source
  double coverage = 0.0;    // fraction of the tile's projected box inside the source image
};

struct TileSpec {
  std::string id;          // "<city>_c<col>_r<row>"
  std::string city;        // name shared by the tiles of one city
  std::vector<std::string> aois;  // AOIs whose images it uses
  int col = 0, row = 0;
  TileGrid grid;           // the city's grid (for ownership at merge)
  GroundBox core;          // owned by this tile
  // What the tile reconstructs: its core grown by the overlap margin towards
  // its neighbours, and the city's bounds grown by the same margin at the
  // city's edge (tiling.cpp: PlanTiles).
  GroundBox extent;
  GeodeticPoint enu_origin;       // the city's shared frame
  double min_ellipsoid_height_m = 0, max_ellipsoid_height_m = 0;  // ellipsoidal
  std::vector<TileImage> images;
  // The part of the core within the city (a city smaller than a tile clips
  // its core): the core cut to the extent less its margin.
  GroundBox ReconstructedCore() const {
    GroundBox b = core;
    b.min_m = b.min_m.cwiseMax((extent.min_m.array() + grid.overlap_m).matrix());
    b.max_m = b.max_m.cwiseMin((extent.max_m.array() - grid.overlap_m).matrix());
    return b;
  }
};

inline Eigen::Vector2i TileGrid::Owner(double east_m, double north_m) const {
  auto index = [](double v, double origin, double size, int count) {
    const double k = std::floor((v - origin) / size);
    return static_cast<int>(std::clamp(k, 0.0, static_cast<double>(count - 1)));
  };
  return {index(east_m, origin_m.x(), tile_m, cols), index(north_m, origin_m.y(), tile_m, rows)};
}

}  // namespace skyfall
