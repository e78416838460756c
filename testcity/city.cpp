#include "testcity/city.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/error.h"
#include "core/format.h"
#include "testcity/hash.h"

namespace skyfall::synth {
namespace {

float LatticeValue(std::int64_t i, std::int64_t j, std::uint64_t seed) {
  return Unit01(SplitMix64(seed ^ SplitMix64(static_cast<std::uint64_t>(i) * 0x1F1F1F1Full ^
                                             SplitMix64(static_cast<std::uint64_t>(j)))));
}

const Eigen::Vector3f kRoofPalette[] = {
    {0.62f, 0.62f, 0.60f}, {0.40f, 0.40f, 0.42f}, {0.55f, 0.27f, 0.20f},
    {0.45f, 0.36f, 0.28f}, {0.82f, 0.82f, 0.80f}, {0.30f, 0.33f, 0.30f}};
const Eigen::Vector3f kFacadePalette[] = {
    {0.78f, 0.72f, 0.60f}, {0.60f, 0.60f, 0.62f}, {0.62f, 0.34f, 0.26f},
    {0.45f, 0.52f, 0.60f}, {0.85f, 0.83f, 0.78f}};

// Street layout shared by generation and car placement: streets run along
// x = k * block and y = k * block (scene frame), `street_width_m` wide.
bool OnStreet(double coord_m, const CityOptions& o) {
  const double r = coord_m - o.block_m * std::round(coord_m / o.block_m);
  return std::abs(r) <= 0.5 * o.street_width_m;
}

// River centre line (x as a function of y) and half width.
double RiverCentreX(double y_m, const CityOptions& o) {
  return 0.72 * o.width_m + 14.0 * std::sin(2.0 * M_PI * y_m / 230.0);
}
constexpr double kRiverHalfWidthM = 9.0;
constexpr double kWaterBelowGroundM = 2.5;
constexpr double kBridgeDeckAboveGroundM = 1.5;

bool InRiver(double x_m, double y_m, const CityOptions& o, double extra_m = 0.0) {
  return o.water && std::abs(x_m - RiverCentreX(y_m, o)) <= kRiverHalfWidthM + extra_m;
}

struct Painter {
  City& city;
  template <typename F>
  void Rect(double x0, double y0, double x1, double y1, F&& paint) {
    const Eigen::Vector2i a = city.CellOf(x0, y0), b = city.CellOf(x1, y1);
    for (int j = std::max(0, a.y()); j <= std::min(city.ny - 1, b.y()); ++j)
      for (int i = std::max(0, a.x()); i <= std::min(city.nx - 1, b.x()); ++i) {
        const Eigen::Vector2d c = city.CellCentre(i, j);
        if (c.x() < x0 || c.x() > x1 || c.y() < y0 || c.y() > y1) continue;
        paint(city.Index(i, j), c);
      }
  }
};

void PaintBuilding(City& city, const Building& b, int index) {
  Painter{city}.Rect(b.x0_m, b.y0_m, b.x1_m, b.y1_m, [&](std::size_t k, const Eigen::Vector2d& c) {
    city.height_m[k] = static_cast<float>(RoofAt(b, c.x(), c.y()));
    city.material[k] = b.gable ? Material::kGableRoof : Material::kFlatRoof;
    city.cls[k] = Dfc2019Class::kBuilding;
    city.object[k] = index;
  });
}

void PaintTree(City& city, double cx, double cy, double radius, double height) {
  const Tree tree{cx, cy, radius, city.TerrainAt(cx, cy), height};
  const auto index = static_cast<std::int32_t>(city.trees.size());
  bool painted = false;
  Painter{city}.Rect(cx - radius, cy - radius, cx + radius, cy + radius,
                     [&](std::size_t k, const Eigen::Vector2d& c) {
                       const double r2 = ((c.x() - cx) * (c.x() - cx) + (c.y() - cy) * (c.y() - cy)) /
                                         (radius * radius);
                       if (r2 > 1.0 || city.material[k] != Material::kGrass) return;
                       city.height_m[k] = static_cast<float>(tree.CrownAt(c.x(), c.y()));
                       city.material[k] = Material::kTree;
                       city.cls[k] = Dfc2019Class::kHighVegetation;
                       city.tree[k] = index;
                       painted = true;
                     });
  if (painted) city.trees.push_back(tree);
}

// Buildings and trees of one city block (the area between four streets).
void FillBlock(City& city, double x0, double y0, double x1, double y1, std::mt19937_64& rng) {
  const CityOptions& o = city.options;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  if (o.water && (InRiver(x0, y0, o, 6) || InRiver(x1, y0, o, 6) || InRiver(x0, y1, o, 6) ||
                  InRiver(x1, y1, o, 6) || InRiver(0.5 * (x0 + x1), 0.5 * (y0 + y1), o, 6))) {
    return;  // river banks stay open
  }
  auto plant_trees = [&](double ax, double ay, double bx, double by, int count) {
    for (int t = 0; t < count; ++t) {
      const double r = 2.0 + 2.5 * u(rng);
      PaintTree(city, ax + (bx - ax) * u(rng), ay + (by - ay) * u(rng), r, 6.0 + 9.0 * u(rng));
    }
  };
  if (u(rng) < 0.15) {  // a park
    plant_trees(x0, y0, x1, y1, 14);
    return;
  }
  // Split the block into 1-2 lots along each axis.
  const int nx = u(rng) < 0.5 ? 1 : 2, ny = u(rng) < 0.5 ? 1 : 2;
  const double sx = x0 + (x1 - x0) * (0.4 + 0.2 * u(rng));
  const double sy = y0 + (y1 - y0) * (0.4 + 0.2 * u(rng));
  for (int a = 0; a < nx; ++a) {
    for (int b = 0; b < ny; ++b) {
      const double lx0 = nx == 1 ? x0 : (a == 0 ? x0 : sx), lx1 = nx == 1 ? x1 : (a == 0 ? sx : x1);
      const double ly0 = ny == 1 ? y0 : (b == 0 ? y0 : sy), ly1 = ny == 1 ? y1 : (b == 0 ? sy : y1);
      const double setback = 2.0 + 3.0 * u(rng);
      Building bld;
      bld.x0_m = lx0 + setback;
      bld.y0_m = ly0 + setback;
      bld.x1_m = lx1 - setback * (0.5 + u(rng));
      bld.y1_m = ly1 - setback * (0.5 + u(rng));
      if (bld.x1_m - bld.x0_m < 8.0 || bld.y1_m - bld.y0_m < 8.0) continue;
      bld.base_m = city.TerrainAt(0.5 * (bld.x0_m + bld.x1_m), 0.5 * (bld.y0_m + bld.y1_m));
      // Heavy-tailed heights: mostly low-rise, a few towers up to the maximum.
      const double rise = 6.0 + (o.max_building_m - 6.0) * std::pow(u(rng), 3.0);
      bld.eave_m = bld.base_m + rise;
      bld.gable = rise < 16.0 && u(rng) < 0.5;
      bld.ridge_along_x = (bld.x1_m - bld.x0_m) >= (bld.y1_m - bld.y0_m);
      const double short_side = std::min(bld.x1_m - bld.x0_m, bld.y1_m - bld.y0_m);
      bld.ridge_m = bld.gable ? bld.eave_m + std::min(5.0, 0.3 * short_side) : bld.eave_m;
      bld.roof_rgb = kRoofPalette[rng() % std::size(kRoofPalette)];
      bld.facade_rgb = kFacadePalette[rng() % std::size(kFacadePalette)];
      city.buildings.push_back(bld);
      PaintBuilding(city, bld, static_cast<int>(city.buildings.size()) - 1);
      plant_trees(lx0, ly0, lx1, ly1, 2);
    }
  }
}

}  // namespace

void CityOptions::Check() const {
  auto need = [](bool ok, const char* field, double v, const char* rule) {
    if (!ok) throw Error("synth", field, FormatDouble(v) + " is invalid: " + rule);
  };
  need(width_m >= 32 && width_m <= 20000, "width_m", width_m, "must be 32..20000 m");
  need(height_m >= 32 && height_m <= 20000, "height_m", height_m, "must be 32..20000 m");
  need(margin_m >= 0 && margin_m <= 1000, "margin_m", margin_m, "must be 0..1000 m");
  need(cell_m > 0.01 && cell_m <= 5, "cell_m", cell_m, "must be 0.01..5 m");
  need(std::isfinite(base_height_m) && std::abs(base_height_m) < 9000, "base_height_m",
       base_height_m, "must be a plausible height");
  need(relief_m >= 0 && relief_m <= 1000, "relief_m", relief_m, "must be 0..1000 m");
  need(max_building_m >= 6 && max_building_m <= 600, "max_building_m", max_building_m,
       "must be 6..600 m");
  need(block_m >= 24 && block_m <= 1000, "block_m", block_m, "must be 24..1000 m");
  need(street_width_m >= 4 && street_width_m < block_m / 2, "street_width_m", street_width_m,
       "must be >= 4 m and below half the block size");
}

Eigen::Vector2i City::CellOf(double x_m, double y_m) const {
  return {static_cast<int>(std::floor((x_m - origin_m.x()) / options.cell_m)),
          static_cast<int>(std::floor((y_m - origin_m.y()) / options.cell_m))};
}

Eigen::Vector2d City::CellCentre(int i, int j) const {
  return origin_m + options.cell_m * Eigen::Vector2d(i + 0.5, j + 0.5);
}

float City::HeightAt(double x_m, double y_m) const {
  const Eigen::Vector2i c = CellOf(x_m, y_m);
  return Inside(c.x(), c.y()) ? height_m[Index(c.x(), c.y())] : min_height_m;
}

double Tree::CrownAt(double x_m, double y_m) const {
  const double r2 = std::min(1.0, ((x_m - cx_m) * (x_m - cx_m) + (y_m - cy_m) * (y_m - cy_m)) / (radius_m * radius_m));
  return base_m + height_m * (0.55 + 0.45 * std::sqrt(1.0 - r2));
}

Eigen::Vector3d Tree::CrownNormal(double x_m, double y_m) const {
  const Eigen::Vector2d d(x_m - cx_m, y_m - cy_m);
  const double rho2 = d.squaredNorm() / (radius_m * radius_m);
  if (rho2 >= 1.0) return Eigen::Vector3d::UnitZ();
  // z = base + H (0.55 + 0.45 s), s = sqrt(1 - |d|^2 / R^2): grad z = -0.45 H d / (R^2 s).
  const double s = std::sqrt(1.0 - rho2);
  return Eigen::Vector3d(0.45 * height_m * d.x(), 0.45 * height_m * d.y(), radius_m * radius_m * s).normalized();
}

namespace {
// A gable's half width across its ridge, and the ridge line's coordinate.
struct GableAxis {
  double half_m, mid_m;
  double across(const Building& b, double x_m, double y_m) const { return (b.ridge_along_x ? y_m : x_m) - mid_m; }
};
GableAxis AxisOf(const Building& b) {
  return b.ridge_along_x ? GableAxis{0.5 * (b.y1_m - b.y0_m), 0.5 * (b.y0_m + b.y1_m)}
                         : GableAxis{0.5 * (b.x1_m - b.x0_m), 0.5 * (b.x0_m + b.x1_m)};
}
}  // namespace

double RoofAt(const Building& b, double x_m, double y_m) {
  const GableAxis a = AxisOf(b);
  if (!b.gable || !(a.half_m > 0)) return b.eave_m;
  return b.eave_m + (b.ridge_m - b.eave_m) * std::max(0.0, 1.0 - std::abs(a.across(b, x_m, y_m)) / a.half_m);
}

Eigen::Vector3d RoofNormal(const Building& b, double x_m, double y_m) {
  const GableAxis a = AxisOf(b);
  if (!b.gable || !(a.half_m > 0) || std::abs(a.across(b, x_m, y_m)) > a.half_m) return Eigen::Vector3d::UnitZ();
  const double slope = (a.across(b, x_m, y_m) > 0 ? 1.0 : -1.0) * (b.ridge_m - b.eave_m) / a.half_m;
  return (b.ridge_along_x ? Eigen::Vector3d(0, slope, 1) : Eigen::Vector3d(slope, 0, 1)).normalized();
}

double City::TerrainAt(double x_m, double y_m) const {
  const CityOptions& o = options;
  const double phase = static_cast<double>(o.seed % 1000) * 0.01;
  constexpr double kHillPeriodM = 1000.0;
  const double hills = 0.5 * o.relief_m * (1.0 + std::sin(2 * M_PI * (0.8 * x_m + 0.6 * y_m) / kHillPeriodM + phase));
  return o.base_height_m + hills + 0.004 * x_m - 0.003 * y_m +
         1.5 * std::sin(2 * M_PI * x_m / 310.0 + phase) * std::cos(2 * M_PI * y_m / 270.0 + phase) +
         0.8 * ValueNoise(x_m, y_m, 45.0, o.seed ^ 0x7E44A1ull);
}

float ValueNoise(double x_m, double y_m, double feature_m, std::uint64_t seed) {
  const double fx = x_m / feature_m, fy = y_m / feature_m;
  const double ix = std::floor(fx), iy = std::floor(fy);
  const double tx = fx - ix, ty = fy - iy;
  const double sx = tx * tx * (3 - 2 * tx), sy = ty * ty * (3 - 2 * ty);
  const auto i = static_cast<std::int64_t>(ix), j = static_cast<std::int64_t>(iy);
  const double a = LatticeValue(i, j, seed), b = LatticeValue(i + 1, j, seed);
  const double c = LatticeValue(i, j + 1, seed), d = LatticeValue(i + 1, j + 1, seed);
  return static_cast<float>((a + (b - a) * sx) + ((c + (d - c) * sx) - (a + (b - a) * sx)) * sy);
}

City GenerateCity(const CityOptions& options) {
  options.Check();
  City city;
  city.options = options;
  // Cell centres fall on multiples of cell_m from the city's lower-left
  // corner, so DSM pixel centres (odd multiples of cell_m when the DSM GSD is
  // 2 * cell_m) sample one column exactly.
  city.origin_m = Eigen::Vector2d::Constant(-options.margin_m - 0.5 * options.cell_m);
  city.nx = static_cast<int>(std::ceil((options.width_m + 2 * options.margin_m) / options.cell_m)) + 1;
  city.ny = static_cast<int>(std::ceil((options.height_m + 2 * options.margin_m) / options.cell_m)) + 1;
  const std::size_t n = static_cast<std::size_t>(city.nx) * city.ny;
  city.height_m.resize(n);
  city.material.assign(n, Material::kGrass);
  city.cls.assign(n, Dfc2019Class::kGround);
  city.object.assign(n, -1);
  city.tree.assign(n, -1);

  // Terrain, river, streets and bridges.
  for (int j = 0; j < city.ny; ++j) {
    for (int i = 0; i < city.nx; ++i) {
      const std::size_t k = city.Index(i, j);
      const Eigen::Vector2d c = city.CellCentre(i, j);
      const double ground = city.TerrainAt(c.x(), c.y());
      city.height_m[k] = static_cast<float>(ground);
      const bool street_x = OnStreet(c.x(), options), street_y = OnStreet(c.y(), options);
      if (InRiver(c.x(), c.y(), options)) {
        if (street_y) {
          city.height_m[k] = static_cast<float>(ground + kBridgeDeckAboveGroundM);
          city.material[k] = Material::kBridge;
          city.cls[k] = Dfc2019Class::kBridge;
        } else {
          city.height_m[k] = static_cast<float>(options.base_height_m - kWaterBelowGroundM);
          city.material[k] = Material::kWater;
          city.cls[k] = Dfc2019Class::kWater;
        }
      } else if (street_x || street_y) {
        city.material[k] = Material::kRoad;
      }
    }
  }

  // Blocks between streets, over the whole grid including the margin.
  std::mt19937_64 rng(options.seed);
  const double half_street = 0.5 * options.street_width_m;
  const int k0 = static_cast<int>(std::floor(-options.margin_m / options.block_m)) - 1;
  const int kx1 = static_cast<int>(std::ceil((options.width_m + options.margin_m) / options.block_m));
  const int ky1 = static_cast<int>(std::ceil((options.height_m + options.margin_m) / options.block_m));
  for (int by = k0; by < ky1; ++by) {
    for (int bx = k0; bx < kx1; ++bx) {
      FillBlock(city, bx * options.block_m + half_street, by * options.block_m + half_street,
                (bx + 1) * options.block_m - half_street, (by + 1) * options.block_m - half_street, rng);
    }
  }
  const auto [lo, hi] = std::minmax_element(city.height_m.begin(), city.height_m.end());
  city.min_height_m = *lo;
  city.max_height_m = *hi;
  // A crown's top or a ridge may fall between cell centres, above its cells.
  for (const Tree& t : city.trees) city.max_height_m = std::max(city.max_height_m, static_cast<float>(t.base_m + t.height_m));
  for (const Building& b : city.buildings) city.max_height_m = std::max(city.max_height_m, static_cast<float>(b.ridge_m));
  return city;
}

City WithCars(const City& base, int cars, std::uint64_t seed) {
  City city = base;
  const CityOptions& o = city.options;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double extent_x = o.width_m + 2 * o.margin_m, extent_y = o.height_m + 2 * o.margin_m;
  int placed = 0;
  for (int attempt = 0; attempt < cars * 20 && placed < cars; ++attempt) {
    const bool along_y = u(rng) < 0.5;  // car on a street running north-south
    const int lanes = static_cast<int>(std::floor((along_y ? extent_x : extent_y) / o.block_m));
    const double street = o.block_m * (std::floor(-o.margin_m / o.block_m) + 1 + static_cast<int>(u(rng) * lanes));
    const double lane = (u(rng) < 0.5 ? -1.0 : 1.0) * 0.25 * o.street_width_m;
    const double along = -o.margin_m + u(rng) * (along_y ? extent_y : extent_x);
    const double cx = along_y ? street + lane : along, cy = along_y ? along : street + lane;
    const double hx = along_y ? 0.9 : 2.25, hy = along_y ? 2.25 : 0.9;
    const Eigen::Vector2i c = city.CellOf(cx, cy);
    if (!city.Inside(c.x(), c.y()) || city.material[city.Index(c.x(), c.y())] != Material::kRoad) continue;
    const int colour = static_cast<int>(rng() % 8);
    const float top = static_cast<float>(city.TerrainAt(cx, cy) + 1.5);
    Painter{city}.Rect(cx - hx, cy - hy, cx + hx, cy + hy, [&](std::size_t k, const Eigen::Vector2d&) {
      if (city.material[k] != Material::kRoad) return;
      city.height_m[k] = top;
      city.material[k] = Material::kCar;
      city.object[k] = -2 - colour;
    });
    ++placed;
  }
  return city;
}

}  // namespace skyfall::synth
