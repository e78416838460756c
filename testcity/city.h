// A procedural satellite-scale city on a height field: terrain, streets,
// buildings with flat and gable roofs, trees, a river with bridges. The
// geometry is known exactly, so tests can compare reconstructions with truth.
//
// Frame: the "scene frame" S has x = easting and y = northing in metres
// relative to the city's lower-left UTM corner, and z = height above the
// WGS84 ellipsoid in metres (the DSM's and the RPCs' height).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace skyfall::synth {

// DFC2019 / ASPRS class codes used by the CLS truth raster.
enum class Dfc2019Class : std::uint8_t {
  kGround = 2,
  kHighVegetation = 5,
  kBuilding = 6,
  kWater = 9,
  kBridge = 17,
};

// What a cell's top surface is made of; drives texture and shading.
enum class Material : std::uint8_t {
  kGrass,
  kRoad,
  kWater,
  kTree,
  kFlatRoof,
  kGableRoof,
  kBridge,
  kCar,
};

struct Building {
  double x0_m, y0_m, x1_m, y1_m;  // footprint in the scene frame
  double base_m;                  // ground height under the building
  double eave_m;                  // height of the walls' top
  double ridge_m;                 // gable ridge height (== eave_m for flat roofs)
  bool gable = false;
  bool ridge_along_x = true;      // ridge direction of a gable roof
  Eigen::Vector3f roof_rgb;       // albedo
  Eigen::Vector3f facade_rgb;
};

// A tree: a crown over a disc of `radius_m`, standing on the terrain at its
// centre, rising from 0.55 to 1 times `height_m` above it (CrownAt).
struct Tree {
  double cx_m, cy_m, radius_m;
  double base_m;    // ground height at the centre
  double height_m;  // crown top above base_m
  // Height of the crown at (x, y); beyond the radius, the height at its rim.
  double CrownAt(double x_m, double y_m) const;
  // Unit upward normal of the crown at (x, y): up beyond the radius, where
  // CrownAt is flat.
  Eigen::Vector3d CrownNormal(double x_m, double y_m) const;
};

// Height of a building's roof at (x, y) inside its footprint: the eaves for
// a flat roof; for a gable, falling linearly from the ridge (the footprint's
// centre line) to the eaves.
double RoofAt(const Building& b, double x_m, double y_m);
// Unit upward normal of that roof at (x, y).
Eigen::Vector3d RoofNormal(const Building& b, double x_m, double y_m);

struct CityOptions {
  double width_m = 256.0;          // city extent along x (east) [m]
  double height_m = 256.0;         // city extent along y (north) [m]
  double margin_m = 96.0;          // extra terrain around it, seen by oblique views [m]
  double cell_m = 0.25;            // height-field cell size [m]
  double base_height_m = -20.0;    // mean ground height above the ellipsoid [m]
  double max_building_m = 80.0;    // tallest building above ground [m]
  double block_m = 72.0;           // street spacing [m]
  double street_width_m = 12.0;
  bool water = true;               // a river with bridges across it
  // [m] relief of hills under the city: a long wave of this peak-to-peak
  // height (period 1 km, so slopes reach relief * pi / 1000, e.g. 31% at
  // 100 m), on top of the gentle default terrain. A river needs flat ground,
  // so relief above 10 m leaves it out.
  double relief_m = 0.0;
  std::uint64_t seed = 1;
  void Check() const;              // throws Error("synth", field, ...)
};

// The height field: columns of `cell_m` square with flat tops. Cell (i, j)
// has its centre at origin + ((i + 0.5) * cell_m, (j + 0.5) * cell_m).
struct City {
  CityOptions options;
  Eigen::Vector2d origin_m;  // scene-frame position of cell (0, 0)'s lower-left corner
  int nx = 0, ny = 0;
  std::vector<float> height_m;           // top height of each column
  std::vector<Material> material;
  std::vector<Dfc2019Class> cls;
  std::vector<std::int32_t> object;      // building index, or -1
  std::vector<Building> buildings;
  std::vector<std::int32_t> tree;        // index into `trees` of a tree's cells, or -1
  std::vector<Tree> trees;
  float min_height_m = 0, max_height_m = 0;

  std::size_t Index(int i, int j) const { return static_cast<std::size_t>(j) * nx + i; }
  bool Inside(int i, int j) const { return i >= 0 && j >= 0 && i < nx && j < ny; }
  // Cell containing a scene-frame point (may be outside the grid).
  Eigen::Vector2i CellOf(double x_m, double y_m) const;
  Eigen::Vector2d CellCentre(int i, int j) const;
  // Height of the column under a point; the lowest height outside the grid.
  float HeightAt(double x_m, double y_m) const;
  // The ground height (terrain without objects) at a point.
  double TerrainAt(double x_m, double y_m) const;
};

City GenerateCity(const CityOptions& options);

// Transient objects (cars) for one acquisition: a copy of the city with cars
// parked on road cells. Deterministic in `seed`.
City WithCars(const City& city, int cars, std::uint64_t seed);

// Deterministic value noise in [0, 1) at scene position (x, y) with the given
// feature size; used for textures.
float ValueNoise(double x_m, double y_m, double feature_m, std::uint64_t seed);

}  // namespace skyfall::synth
