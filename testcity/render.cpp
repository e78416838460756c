#include "testcity/render.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "testcity/hash.h"

namespace skyfall::synth {
namespace {

// Which face of a column a ray hit.
enum class Face { kTop, kWall };

struct Hit {
  bool found = false;
  Eigen::Vector3d point;
  int i = 0, j = 0;
  Face face = Face::kTop;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // of the surface hit (CastDown sets all but flat tops')
};

// Bare ground (grass, streets): its columns sample the smooth terrain, and
// rays and shadows meet the terrain itself. Drawn as flat-topped columns, a
// hill's cells would be stairs (7.5 cm per 0.25 m cell on a 30% slope)
// whose risers and their shadows striped the slopes, differently in every
// view and at every sun position: a texture no real hill has.
bool OnTerrain(const City& city, std::size_t k) {
  return city.material[k] == Material::kGrass || city.material[k] == Material::kRoad;
}

// Upper bound of the terrain's departure within a cell from the height of
// its column (the terrain at the cell's centre): the steepest slope (the
// hills' relief * pi / 1000 plus 0.1 for the gentle terrain) times half the
// cell's diagonal, with margin. Rays and shadows further above a terrain
// cell's column than this cannot meet the terrain there, so the terrain is
// evaluated only close to it.
double TerrainBandM(const City& city) {
  const double steepest = 0.1 + city.options.relief_m * M_PI / 1000.0;
  return 0.05 + 0.75 * city.options.cell_m * steepest;
}

// Unit normal of the terrain at (x, y), from central differences.
Eigen::Vector3d TerrainNormal(const City& city, double x, double y) {
  constexpr double h = 0.05;
  const double dx = (city.TerrainAt(x + h, y) - city.TerrainAt(x - h, y)) / (2 * h);
  const double dy = (city.TerrainAt(x, y + h) - city.TerrainAt(x, y - h)) / (2 * h);
  return Eigen::Vector3d(-dx, -dy, 1.0).normalized();
}

// Height of a point above the terrain.
double AboveTerrain(const City& city, const Eigen::Vector3d& p) { return p.z() - city.TerrainAt(p.x(), p.y()); }

// Grid traversal state for a ray in the xy plane (Amanatides & Woo).
struct Traversal {
  int i, j, step_i, step_j;
  double t_max_x, t_max_y, t_delta_x, t_delta_y;

  Traversal(const City& city, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
    const double cell = city.options.cell_m;
    const Eigen::Vector2i c = city.CellOf(o.x(), o.y());
    i = c.x();
    j = c.y();
    const double inf = std::numeric_limits<double>::infinity();
    step_i = d.x() > 0 ? 1 : -1;
    step_j = d.y() > 0 ? 1 : -1;
    const double x0 = city.origin_m.x() + (i + (d.x() > 0 ? 1 : 0)) * cell;
    const double y0 = city.origin_m.y() + (j + (d.y() > 0 ? 1 : 0)) * cell;
    t_max_x = d.x() != 0 ? (x0 - o.x()) / d.x() : inf;
    t_max_y = d.y() != 0 ? (y0 - o.y()) / d.y() : inf;
    t_delta_x = d.x() != 0 ? cell / std::abs(d.x()) : inf;
    t_delta_y = d.y() != 0 ? cell / std::abs(d.y()) : inf;
  }
  // Moves to the next cell; returns the t at which it was entered and
  // whether the crossed boundary was an x (east/west) face.
  double Step(bool* crossed_x) {
    if (t_max_x < t_max_y) {
      i += step_i;
      *crossed_x = true;
      const double t = t_max_x;
      t_max_x += t_delta_x;
      return t;
    }
    j += step_j;
    *crossed_x = false;
    const double t = t_max_y;
    t_max_y += t_delta_y;
    return t;
  }
  double NextBoundary() const { return std::min(t_max_x, t_max_y); }
};

// Where a ray crosses a surface within [t0, t1], given `below(t)`, false at
// t0 and true at t1: bisection, to well under a mm.
template <typename Below>
double Crossing(const Below& below, double t0, double t1) {
  for (int it = 0; it < 40; ++it) {
    const double m = 0.5 * (t0 + t1);
    (below(m) ? t1 : t0) = m;
  }
  return t1;
}

// Where a descending ray meets the terrain within [t0, t1] (it is above
// the terrain at t0 and not above at t1).
double TerrainCrossing(const City& city, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0, double t1) {
  return Crossing([&](double t) { return AboveTerrain(city, o + t * d) <= 0; }, t0, t1);
}

// Gable roofs and tree crowns are smooth too: as flat-topped 0.25 m
// columns a roof's slope and a crown's dome would be stairs whose risers
// (lit as walls) and their shadows differ in every view and at every sun
// position, a texture no roof or tree has. A cell of either stands for its
// object's own surface: rays and shadows meet that surface within the cell.
// (Terrain, nearly flat within a cell, is handled apart; see OnTerrain.)
enum class SmoothKind { kNone, kGableRoof, kCrown };
struct SmoothTop {
  SmoothKind kind = SmoothKind::kNone;
  int id = -1;  // building or tree index
  bool operator==(const SmoothTop& o) const { return kind == o.kind && id == o.id; }
};

SmoothTop SmoothTopOf(const City& city, std::size_t k) {
  if (city.material[k] == Material::kGableRoof) return {SmoothKind::kGableRoof, city.object[k]};
  if (city.material[k] == Material::kTree && city.tree[k] >= 0) return {SmoothKind::kCrown, city.tree[k]};
  return {};
}

double SmoothTopAt(const City& city, const SmoothTop& s, double x, double y) {
  return s.kind == SmoothKind::kGableRoof ? RoofAt(city.buildings[s.id], x, y) : city.trees[s.id].CrownAt(x, y);
}

// The highest the surface gets anywhere: above this a ray cannot meet it.
double SmoothTopMax(const City& city, const SmoothTop& s) {
  if (s.kind == SmoothKind::kGableRoof) return city.buildings[s.id].ridge_m;
  const Tree& t = city.trees[s.id];
  return t.base_m + t.height_m;
}

Eigen::Vector3d SmoothTopNormal(const City& city, const SmoothTop& s, const Eigen::Vector3d& p) {
  return s.kind == SmoothKind::kGableRoof ? RoofNormal(city.buildings[s.id], p.x(), p.y())
                                          : city.trees[s.id].CrownNormal(p.x(), p.y());
}

// Samples of a ray's way through a cell, [t0, t1], at which it is compared
// with a smooth top: the roof's ridge or the crown's dome may rise between
// the ends, so the ends alone would miss a ray grazing over it. A cell's
// way is at most 0.36 m across, so samples are under 5 cm apart: a ray can
// pass over at most the tip of a ridge or dome between two of them, and
// then meets the surface on entering the next cell.
constexpr int kSmoothSamples = 8;

// First t in [t0, t1] where the ray is at or below the smooth top, or -1.
double SmoothTopCrossing(const City& city, const SmoothTop& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                         double t0, double t1) {
  auto below = [&](double t) {
    const Eigen::Vector3d p = o + t * d;
    return p.z() <= SmoothTopAt(city, s, p.x(), p.y());
  };
  double prev = t0;
  for (int k = 1; k <= kSmoothSamples; ++k) {
    const double t = t0 + (t1 - t0) * k / kSmoothSamples;
    if (below(t)) return Crossing(below, prev, t);
    prev = t;
  }
  return -1.0;
}

// First surface hit by a descending ray starting above every column.
Hit CastDown(const City& city, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  Hit hit;
  Traversal tr(city, o, d);
  double t_enter = 0.0;
  bool crossed_x = false, came_from_terrain = false;
  SmoothTop came_from_smooth;
  const double band = TerrainBandM(city);
  auto found = [&](const Eigen::Vector3d& point, Face face) {
    hit.found = true;
    hit.point = point;
    hit.face = face;
    hit.i = tr.i;
    hit.j = tr.j;
    return hit;
  };
  for (int guard = 0; guard < 4 * (city.nx + city.ny); ++guard) {
    if (!city.Inside(tr.i, tr.j)) return hit;
    const std::size_t k = city.Index(tr.i, tr.j);
    const double h = city.height_m[k];
    const double z_enter = o.z() + t_enter * d.z();
    // A vertical ray (an orthophoto's) never crosses a cell boundary: it
    // leaves its column at the city's floor instead.
    double t_exit = tr.NextBoundary();
    const bool vertical = !std::isfinite(t_exit);
    if (vertical) t_exit = (city.min_height_m - 1.0 - o.z()) / d.z();
    const double z_exit = o.z() + t_exit * d.z();
    const bool terrain = OnTerrain(city, k);
    const SmoothTop smooth = SmoothTopOf(city, k);
    auto wall_normal = [&] { return crossed_x ? Eigen::Vector3d(-tr.step_i, 0, 0) : Eigen::Vector3d(0, -tr.step_j, 0); };
    if (smooth.kind != SmoothKind::kNone) {
      const Eigen::Vector3d p_enter = o + t_enter * d;
      if (t_enter > 0 && p_enter.z() <= SmoothTopAt(city, smooth, p_enter.x(), p_enter.y())) {
        if (smooth == came_from_smooth) {  // below the surface on entering: it was crossed at the boundary
          hit.normal = SmoothTopNormal(city, smooth, p_enter);
          return found(p_enter, Face::kTop);
        }
        // A building's wall, a crown's side where its cells end, or the step
        // between two crowns: a wall facing the cell the ray came from.
        hit.normal = wall_normal();
        return found(p_enter, Face::kWall);
      }
      if (z_exit <= SmoothTopMax(city, smooth)) {
        const double t = SmoothTopCrossing(city, smooth, o, d, t_enter, t_exit);
        if (t >= 0) {
          const Eigen::Vector3d p = o + t * d;
          hit.normal = SmoothTopNormal(city, smooth, p);
          return found(p, Face::kTop);
        }
      }
    } else {
      const bool enters_below_top = z_enter <= h && t_enter > 0;
      if (enters_below_top && !(terrain && came_from_terrain)) {
        // The ray meets this column's wall (between terrain cells there is none).
        hit.normal = wall_normal();
        return found(o + t_enter * d, Face::kWall);
      }
      if (terrain && z_exit <= h + band && AboveTerrain(city, o + t_exit * d) <= 0) {
        const double t = AboveTerrain(city, o + t_enter * d) <= 0 ? t_enter : TerrainCrossing(city, o, d, t_enter, t_exit);
        const Eigen::Vector3d p = o + t * d;
        hit.normal = TerrainNormal(city, p.x(), p.y());
        return found(p, Face::kTop);
      }
      if (!terrain && z_exit <= h) return found(o + ((h - o.z()) / d.z()) * d, Face::kTop);  // down on the top
    }
    if (vertical || z_exit < city.min_height_m - 1.0) return hit;  // a vertical ray has no next column
    came_from_terrain = terrain;
    came_from_smooth = smooth;
    t_enter = tr.Step(&crossed_x);
  }
  return hit;
}

// Whether the way from `p` towards the sun is blocked by a column.
bool InShadow(const City& city, const Eigen::Vector3d& p, const Eigen::Vector3d& sun) {
  if (sun.z() <= 0) return true;
  Traversal tr(city, p, sun);
  double t_enter = 0.0;
  bool crossed_x = false;
  const double band = TerrainBandM(city);
  for (int guard = 0; guard < 4 * (city.nx + city.ny); ++guard) {
    if (!city.Inside(tr.i, tr.j)) return false;
    const double z_enter = p.z() + t_enter * sun.z();
    if (z_enter > city.max_height_m) return false;
    const std::size_t k = city.Index(tr.i, tr.j);
    const SmoothTop smooth = SmoothTopOf(city, k);
    if (OnTerrain(city, k)) {
      // The terrain is smooth, and the ray straight: it is below the
      // terrain somewhere in the cell only if it is at one of its ends.
      const double t_exit = tr.NextBoundary();
      if (z_enter < city.height_m[k] + band &&
          ((t_enter > 0 && AboveTerrain(city, p + t_enter * sun) < -1e-4) ||
           AboveTerrain(city, p + t_exit * sun) < -1e-4))
        return true;
    } else if (smooth.kind != SmoothKind::kNone) {
      // A ridge or a dome may rise between the cell's ends: sampled.
      if (z_enter < SmoothTopMax(city, smooth)) {
        const double t_exit = tr.NextBoundary();
        for (int s = 0; s <= kSmoothSamples; ++s) {
          const double t = t_enter + (t_exit - t_enter) * s / kSmoothSamples;
          if (t <= 0) continue;
          const Eigen::Vector3d q = p + t * sun;
          if (q.z() < SmoothTopAt(city, smooth, q.x(), q.y()) - 1e-4) return true;
        }
      }
    } else if (t_enter > 0 && z_enter < city.height_m[k] - 1e-4) {
      return true;  // ascending: the lowest point of the ray in a cell is where it enters
    }
    t_enter = tr.Step(&crossed_x);
  }
  return false;
}

float Hash01(std::uint64_t a, std::uint64_t b) {
  std::uint64_t x = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull);
  x = (x ^ (x >> 31)) * 0xBF58476D1CE4E5B9ull;
  x ^= x >> 29;
  return Unit01(x);
}

const Eigen::Vector3f kCarPalette[8] = {{0.85f, 0.85f, 0.85f}, {0.1f, 0.1f, 0.1f},
                                        {0.7f, 0.1f, 0.1f},    {0.15f, 0.25f, 0.6f},
                                        {0.6f, 0.6f, 0.62f},   {0.9f, 0.8f, 0.2f},
                                        {0.2f, 0.45f, 0.25f},  {0.5f, 0.5f, 0.55f}};

// Distance to the nearest street centre line along one axis.
double StreetOffset(double coord_m, double block_m) {
  return coord_m - block_m * std::round(coord_m / block_m);
}

Eigen::Vector3f Albedo(const City& city, const Hit& hit) {
  const std::size_t k = city.Index(hit.i, hit.j);
  const Material m = city.material[k];
  const double x = hit.point.x(), y = hit.point.y(), z = hit.point.z();
  const std::uint64_t seed = city.options.seed;
  const int obj = city.object[k];
  const bool wall = hit.face == Face::kWall;
  if ((m == Material::kFlatRoof || m == Material::kGableRoof) && wall) {
    // Facades: floors of 3.2 m with a row of windows each.
    const Building& b = city.buildings[obj];
    const double u = std::abs(hit.normal.x()) > 0 ? y : x;
    const double v = z - b.base_m;
    const bool window = std::fmod(v, 3.2) > 1.0 && std::fmod(v, 3.2) < 2.3 &&
                        std::fmod(std::abs(u), 2.6) > 0.6 && std::fmod(std::abs(u), 2.6) < 2.0 &&
                        z < b.eave_m - 0.5;
    if (window) return {0.16f, 0.20f, 0.27f};
    return b.facade_rgb * (0.9f + 0.2f * ValueNoise(u, z, 1.3, seed + obj));
  }
  switch (m) {
    case Material::kGrass: {
      const float a = ValueNoise(x, y, 9.0, seed + 11);
      const Eigen::Vector3f green(0.30f, 0.38f, 0.18f), soil(0.45f, 0.40f, 0.28f);
      return (green + (soil - green) * a) * (0.8f + 0.4f * ValueNoise(x, y, 1.1, seed + 12));
    }
    case Material::kRoad: {
      const double ox = StreetOffset(x, city.options.block_m), oy = StreetOffset(y, city.options.block_m);
      const bool ns = std::abs(ox) <= 0.5 * city.options.street_width_m;
      const double across = ns ? ox : oy, along = ns ? y : x;
      if (std::abs(across) < 0.15 && std::fmod(std::abs(along), 6.0) < 3.0) return {0.85f, 0.85f, 0.8f};
      return Eigen::Vector3f::Constant(0.27f * (0.85f + 0.3f * ValueNoise(x, y, 0.8, seed + 13)));
    }
    case Material::kWater:
      return Eigen::Vector3f(0.07f, 0.14f, 0.20f) * (0.9f + 0.2f * ValueNoise(x, y, 3.0, seed + 14));
    case Material::kTree:
      return Eigen::Vector3f(0.12f, 0.30f, 0.10f) * (0.6f + 0.8f * ValueNoise(x, y, 0.9, seed + 15));
    case Material::kFlatRoof: {
      const Building& b = city.buildings[obj];
      const float spots = ValueNoise(x, y, 2.5, seed + 16 + obj) > 0.78f ? 0.65f : 1.0f;
      return b.roof_rgb * spots * (0.85f + 0.3f * ValueNoise(x, y, 1.2, seed + 17 + obj));
    }
    case Material::kGableRoof: {
      const Building& b = city.buildings[obj];
      const double across = b.ridge_along_x ? y : x;
      const float rows = std::fmod(std::abs(across), 0.6) < 0.12 ? 0.75f : 1.0f;  // tile courses
      return b.roof_rgb * rows * (0.9f + 0.2f * ValueNoise(x, y, 2.0, seed + 18 + obj));
    }
    case Material::kBridge:
      return Eigen::Vector3f(0.55f, 0.55f, 0.52f) * (0.9f + 0.2f * ValueNoise(x, y, 1.0, seed + 19));
    case Material::kCar:
      return kCarPalette[(-obj - 2) & 7];
  }
  return {0.5f, 0.5f, 0.5f};
}

// The albedo a pixel records: the surface's texture averaged over the
// pixel's footprint, as a detector integrates the light over its area. The
// footprint is taken on the plane through the hit with the surface's normal,
// at `sub` x `sub` points where rays through a regular grid of the pixel
// meet that plane; shading and shadow stay those of the pixel's centre, and
// so do the material and object the texture is of: a footprint across an
// object's edge is textured as the object at its centre.
// Point-sampled, textures finer than two pixels (a gable's 0.6 m tile
// courses, road markings) alias into a moire that differs in every view.
template <typename RayFn>
Eigen::Vector3f PixelAlbedo(const City& city, const Hit& hit, const Eigen::Vector3d& normal, int sub, const RayFn& ray,
                            int col, int row) {
  if (sub <= 1) return Albedo(city, hit);
  // A sub-point further than this from the centre's hit (a ray grazing the
  // plane) takes the centre's albedo instead.
  const double max_offset_m = 4.0;
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  for (int sy = 0; sy < sub; ++sy)
    for (int sx = 0; sx < sub; ++sx) {
      const auto [o, d] = ray(col + (sx + 0.5) / sub - 0.5, row + (sy + 0.5) / sub - 0.5);
      const double along = normal.dot(d);
      Hit at = hit;
      if (std::abs(along) > 1e-6) {
        const Eigen::Vector3d q = o + (normal.dot(hit.point - o) / along) * d;
        if ((q - hit.point).norm() < max_offset_m) at.point = q;
      }
      sum += Albedo(city, at);
    }
  return sum / static_cast<float>(sub * sub);
}

// Share of the direct sunlight an opaque cloud takes (thick cumulus).
constexpr float kCloudShadowDepth = 0.85f;
// A cloud's colour seen from above: sunlit cumulus, brighter than any roof
// (with a bright date's gain it saturates, as real cloud tops do).
constexpr float kCloudColour[3] = {0.93f, 0.94f, 0.96f};

// The colour (before the sensor's tint, gain and noise) and hit of the ray
// through pixel (col, row): the surface's albedo over the pixel's footprint,
// lit by the sun unless in shadow, plus the sky's ambient share.
template <typename RayFn>
Hit ShadePixel(const City& city, const Lighting& lighting, const RayFn& ray, int col, int row,
               Eigen::Vector3f* colour) {
  const Eigen::Vector3d sun = lighting.sun_scene.normalized();
  const auto [o_scene, d_scene] = ray(col, row);
  const Hit hit = CastDown(city, o_scene, d_scene);
  *colour = Eigen::Vector3f(0.5f, 0.5f, 0.5f);
  if (!hit.found) return hit;
  const Eigen::Vector3d& normal = hit.normal;
  const double lambert = std::max(0.0, normal.dot(sun));
  const bool lit = lambert > 0 && !(lighting.cast_shadows && InShadow(city, hit.point + 1e-3 * normal, sun));
  // A cloud between the surface and the sun takes most of the direct light
  // (its edge a soft penumbra); the sky's ambient share stays.
  const float cloud_shade = lit ? 1.0f - kCloudShadowDepth * lighting.clouds.OpacityAlong(hit.point, sun) : 1.0f;
  const float light =
      lighting.ambient + (1.0f - lighting.ambient) * static_cast<float>(lit ? lambert : 0.0) * 1.3f * cloud_shade;
  *colour = PixelAlbedo(city, hit, normal, std::max(1, lighting.subpixels), ray, col, row) * light;
  return hit;
}

// The optics' blur: a Gaussian point-spread function of `sigma_px`, applied
// along rows and then columns, edges clamped.
void BlurImage(std::vector<Eigen::Vector3f>& image, int width, int height, float sigma_px) {
  const int radius = static_cast<int>(std::ceil(3.0f * sigma_px));
  std::vector<float> kernel(2 * radius + 1);
  float total = 0;
  for (int k = -radius; k <= radius; ++k) total += kernel[k + radius] = std::exp(-0.5f * k * k / (sigma_px * sigma_px));
  for (float& k : kernel) k /= total;
  auto pass = [&](int lines, int length, auto at) {
    tbb::parallel_for(0, lines, [&](int line) {
      std::vector<Eigen::Vector3f> out(length, Eigen::Vector3f::Zero());
      for (int i = 0; i < length; ++i)
        for (int k = -radius; k <= radius; ++k) out[i] += kernel[k + radius] * at(line, std::clamp(i + k, 0, length - 1));
      for (int i = 0; i < length; ++i) at(line, i) = out[i];
    });
  };
  pass(height, width, [&](int row, int col) -> Eigen::Vector3f& { return image[static_cast<std::size_t>(row) * width + col]; });
  pass(width, height, [&](int col, int row) -> Eigen::Vector3f& { return image[static_cast<std::size_t>(row) * width + col]; });
}

// The colour of haze's path radiance (a bright sky's blue-grey).
constexpr float kHazeColour[3] = {0.55f, 0.58f, 0.64f};

// A sensor's 8-bit value of a colour channel: haze, tint, gain, and +-1 DN
// of noise and lighting.noise_dn of Gaussian noise (Box-Muller on two
// SplitMix64 draws keyed by the view and the pixel's band) unless `noise`
// is off.
std::uint8_t SensorValue(const Lighting& lighting, float colour, int channel, std::size_t pixel, bool noise) {
  float dn = noise ? (Hash01(lighting.noise_seed + channel, pixel) - 0.5f) * 2.0f : 0.0f;
  if (noise && lighting.noise_dn > 0) {
    const std::uint64_t sample = 3 * static_cast<std::uint64_t>(pixel) + channel;
    const std::uint64_t view_key = SplitMix64(lighting.noise_seed);
    const float u1 = std::max(Unit01(SplitMix64(view_key + 2 * sample)), 1e-7f);
    const float u2 = Unit01(SplitMix64(view_key + 2 * sample + 1));
    dn += lighting.noise_dn * std::sqrt(-2.0f * std::log(u1)) * std::cos(6.2831853f * u2);
  }
  const float seen = colour * (1.0f - lighting.haze) + lighting.haze * kHazeColour[channel];
  const float v = seen * lighting.tint[channel] * lighting.gain * 255.0f + dn;
  return static_cast<std::uint8_t>(std::min(255.0f, std::max(0.0f, v) + 0.5f));
}

}  // namespace

float CloudLayer::OpacityAt(double x_m, double y_m) const {
  double sum = 0.0;
  for (const CloudPuff& p : puffs) {
    const double dx = x_m - p.centre_m.x(), dy = y_m - p.centre_m.y();
    const double q = (dx * dx + dy * dy) / (p.radius_m * p.radius_m);
    if (q < 1.0) sum += (1.0 - q) * (1.0 - q);
  }
  return static_cast<float>(std::min(1.0, sum));
}

float CloudLayer::OpacityAlong(const Eigen::Vector3d& from, const Eigen::Vector3d& direction) const {
  if (puffs.empty() || std::abs(direction.z()) < 1e-9) return 0.0f;
  const double t = (height_m - from.z()) / direction.z();
  return OpacityAt(from.x() + t * direction.x(), from.y() + t * direction.y());
}

Eigen::Vector2d SatelliteCamera::Project(const Eigen::Vector3d& enu_m) const {
  const Eigen::Vector3d p = cam_from_enu * (enu_m - centre_enu_m);
  return {focal_px * p.x() / p.z() + principal_px.x(), focal_px * p.y() / p.z() + principal_px.y()};
}

Eigen::Vector3d SatelliteCamera::RayDirectionEnu(double col, double row) const {
  const Eigen::Vector3d cam((col - principal_px.x()) / focal_px, (row - principal_px.y()) / focal_px, 1.0);
  return (cam_from_enu.transpose() * cam).normalized();
}

RenderedView RenderView(const City& city, const SatelliteCamera& camera,
                        const SceneFromEnu& scene_from_enu, const Lighting& lighting) {
  RenderedView view;
  view.width_px = camera.width_px;
  view.height_px = camera.height_px;
  const std::size_t n = static_cast<std::size_t>(camera.width_px) * camera.height_px;
  view.rgb.assign(3 * n, 0);
  view.hit_scene.assign(n, Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN()));
  view.hit_object.assign(n, -1);
  // Rays start above the tallest column: the traversal sees only columns
  // below its start. The scene's z is the ellipsoidal height, ENU's up is
  // measured from the frame's origin (the city's base height, the scene
  // point of ENU's origin); over the city the two differ by that offset
  // and millimetres (1 m of margin covers those).
  const double start_z_enu = city.max_height_m + 1.0 - scene_from_enu.offset_m.z() + 1.0;

  // The ray through image point (col, row), in the scene frame, starting
  // above every column. (A camera below that height, such as a low orbit
  // view, starts at itself.)
  auto ray = [&](double col, double row) {
    const Eigen::Vector3d d_enu = camera.RayDirectionEnu(col, row);
    const double t_start = std::max(0.0, (start_z_enu - camera.centre_enu_m.z()) / d_enu.z());
    return std::make_pair(scene_from_enu.Apply(camera.centre_enu_m + t_start * d_enu),
                          Eigen::Vector3d((scene_from_enu.linear * d_enu).normalized()));
  };
  std::atomic<std::size_t> covered{0};
  std::vector<Eigen::Vector3f> radiance(n);  // what reaches the optics, before blur and the detector
  tbb::parallel_for(tbb::blocked_range<int>(0, camera.height_px), [&](const tbb::blocked_range<int>& rows) {
    for (int r = rows.begin(); r < rows.end(); ++r) {
      for (int c = 0; c < camera.width_px; ++c) {
        const std::size_t p = static_cast<std::size_t>(r) * camera.width_px + c;
        Eigen::Vector3f& colour = radiance[p];
        const Hit hit = ShadePixel(city, lighting, ray, c, r, &colour);
        if (!lighting.clouds.puffs.empty()) {
          const auto [o_scene, d_scene] = ray(c, r);
          const float cloud = lighting.clouds.OpacityAlong(o_scene, d_scene);
          for (int ch = 0; ch < 3; ++ch) colour[ch] = (1.0f - cloud) * colour[ch] + cloud * kCloudColour[ch];
          if (cloud >= 0.5f) covered.fetch_add(1, std::memory_order_relaxed);
        }
        if (hit.found) {
          view.hit_scene[p] = hit.point.cast<float>();
          const std::int32_t obj = city.object[city.Index(hit.i, hit.j)];
          view.hit_object[p] = obj >= 0 ? obj : -1;
        }
      }
    }
  });
  if (lighting.blur_px > 0) BlurImage(radiance, camera.width_px, camera.height_px, lighting.blur_px);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t p) {
    for (int ch = 0; ch < 3; ++ch) view.rgb[3 * p + ch] = SensorValue(lighting, radiance[p][ch], ch, p, true);
  });
  view.cloud_covered_fraction = n ? static_cast<double>(covered.load()) / static_cast<double>(n) : 0.0;
  return view;
}

std::vector<std::uint8_t> RenderOrtho(const City& city, const Lighting& lighting_of_view, double x0_m,
                                      double y_top_m, double gsd_m, int width_px, int height_px) {
  // The ground's truth: lit as the view is, under a clear sky.
  Lighting lighting = lighting_of_view;
  lighting.clouds = CloudLayer();
  std::vector<std::uint8_t> rgb(3 * static_cast<std::size_t>(width_px) * height_px, 0);
  const double start_z = city.max_height_m + 2.0;
  // Vertical rays through the grid's pixels: (col, row) = (0, 0) is the
  // centre of the north-west pixel.
  auto ray = [&](double col, double row) {
    return std::make_pair(Eigen::Vector3d(x0_m + (col + 0.5) * gsd_m, y_top_m - (row + 0.5) * gsd_m, start_z),
                          Eigen::Vector3d(0, 0, -1));
  };
  tbb::parallel_for(tbb::blocked_range<int>(0, height_px), [&](const tbb::blocked_range<int>& rows) {
    for (int r = rows.begin(); r < rows.end(); ++r)
      for (int c = 0; c < width_px; ++c) {
        const std::size_t p = static_cast<std::size_t>(r) * width_px + c;
        Eigen::Vector3f colour;
        ShadePixel(city, lighting, ray, c, r, &colour);
        for (int ch = 0; ch < 3; ++ch) rgb[3 * p + ch] = SensorValue(lighting, colour[ch], ch, p, false);
      }
  });
  return rgb;
}

}  // namespace skyfall::synth
