#include "dense/hole_fill.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>

#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/format.h"
#include "core/stats.h"

namespace skyfall {
namespace {

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();

// Sliding minimum of width 2r+1 over `n` values at stride `stride` from
// `in` into `out` (van Herk / Gil-Werman: three comparisons per value,
// whatever r). NaN and the outside count as +infinity.
void SlidingMin1d(const float* in, float* out, int n, std::size_t stride, int r, WindowEdge edge,
                  std::vector<float>& prefix, std::vector<float>& suffix) {
  const float inf = std::numeric_limits<float>::infinity();
  const int w = 2 * r + 1;
  const int padded = ((n + 2 * r + w - 1) / w) * w;  // r of +inf on the left, the rest on the right
  prefix.resize(padded);
  suffix.resize(padded);
  auto value = [&](int p) {
    const int x = p - r;
    if (x < 0 || x >= n) return inf;
    const float v = in[static_cast<std::size_t>(x) * stride];
    return v == v ? v : inf;
  };
  for (int start = 0; start < padded; start += w) {
    prefix[start] = value(start);
    for (int p = start + 1; p < start + w; ++p) prefix[p] = std::min(prefix[p - 1], value(p));
    suffix[start + w - 1] = value(start + w - 1);
    for (int p = start + w - 2; p >= start; --p) suffix[p] = std::min(suffix[p + 1], value(p));
  }
  // Window of output x: padded positions [x, x + 2r].
  for (int x = 0; x < n; ++x) out[static_cast<std::size_t>(x) * stride] = std::min(suffix[x], prefix[x + 2 * r]);
  if (edge == WindowEdge::kShift) {
    // Windows moved inside: near an edge, the window flush with it; the
    // whole line when it is shorter than a window.
    auto at = [&](int x) -> float& { return out[static_cast<std::size_t>(x) * stride]; };
    if (n >= w) {
      for (int x = 0; x < r; ++x) at(x) = at(r);
      for (int x = n - r; x < n; ++x) at(x) = at(n - 1 - r);
    } else {
      float m = inf;
      for (int p = r; p < r + n; ++p) m = std::min(m, value(p));
      for (int x = 0; x < n; ++x) at(x) = m;
    }
  }
}

}  // namespace

std::vector<float> MinFilter(const std::vector<float>& h, int nx, int ny, int r, WindowEdge edge) {
  std::vector<float> rows(h.size()), out(h.size()), prefix, suffix;
  for (int j = 0; j < ny; ++j) {
    const std::size_t row = static_cast<std::size_t>(j) * nx;
    SlidingMin1d(h.data() + row, rows.data() + row, nx, 1, r, edge, prefix, suffix);
  }
  for (int i = 0; i < nx; ++i) SlidingMin1d(rows.data() + i, out.data() + i, ny, nx, r, edge, prefix, suffix);
  for (float& x : out)
    if (!std::isfinite(x)) x = kNan;
  return out;
}

namespace {

// Morphological opening with a flat (2r+1)^2 square, moved inside or cut
// at the grid's edges: the highest of the square minima (NaN cells ignored).
std::vector<float> Opening(const std::vector<float>& h, int nx, int ny, int r, WindowEdge edge) {
  std::vector<float> eroded = MinFilter(h, nx, ny, r, edge);
  for (float& x : eroded) x = -x;  // the maximum filter as a minimum of negatives
  std::vector<float> opened = MinFilter(eroded, nx, ny, r, edge);
  for (float& x : opened) x = -x;
  return opened;
}

void CheckGrid(const std::vector<float>& h, int nx, int ny) {
  if (nx < 1 || ny < 1 || h.size() != static_cast<std::size_t>(nx) * ny)
    throw Error("dense", "height grid", "size " + std::to_string(h.size()) + " is not nx*ny");
}

// Calls visit(n) for each of the 4 grid neighbours n of cell k.
template <typename Visit>
void ForEachNeighbour4(std::size_t k, int nx, int ny, Visit visit) {
  const int i = static_cast<int>(k % nx), j = static_cast<int>(k / nx);
  const int di[4] = {1, -1, 0, 0}, dj[4] = {0, 0, 1, -1};
  for (int d = 0; d < 4; ++d) {
    const int a = i + di[d], b = j + dj[d];
    if (a < 0 || b < 0 || a >= nx || b >= ny) continue;
    visit(static_cast<std::size_t>(b) * nx + a);
  }
}

// A plane z = c0 + c1 * (i - ci) + c2 * (j - cj) in cell coordinates,
// centred on the cells it was fitted to (so the normal equations stay well
// conditioned far from the grid's origin).
struct CellPlane {
  double ci = 0, cj = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  double At(double i, double j) const { return c[0] + c[1] * (i - ci) + c[2] * (j - cj); }
};

// Least-squares plane through the cells `used` of `h`; nullopt when they do
// not span a plane (fewer than 3, or all on one line).
std::optional<CellPlane> FitPlane(const std::vector<float>& h, int nx, const std::vector<std::size_t>& used) {
  if (used.size() < 3) return std::nullopt;
  CellPlane plane;
  for (std::size_t k : used) {
    plane.ci += static_cast<double>(k % nx);
    plane.cj += static_cast<double>(k / nx);
  }
  plane.ci /= static_cast<double>(used.size());
  plane.cj /= static_cast<double>(used.size());
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (std::size_t k : used) {
    const Eigen::Vector3d x(1.0, static_cast<double>(k % nx) - plane.ci, static_cast<double>(k / nx) - plane.cj);
    normal += x * x.transpose();
    rhs += x * static_cast<double>(h[k]);
  }
  // The spread of the cells around their centre: a line (or a point) leaves
  // the tilt across it free.
  const Eigen::Matrix2d spread = normal.bottomRightCorner<2, 2>();
  if (!(spread.determinant() > 1e-6 * spread.trace() * spread.trace())) return std::nullopt;
  plane.c = normal.ldlt().solve(rhs);
  return plane;
}

// Harmonic interpolation on a small grid: cells with `known` keep their
// value, the others converge to the mean of their 4 neighbours
// (successive over-relaxation).
void HarmonicFill(std::vector<double>& v, const std::vector<std::uint8_t>& known, int nx, int ny) {
  constexpr double kOmega = 1.8;           // over-relaxation: a few hundred sweeps for a 100-block grid
  constexpr double kConvergedM = 1e-5;     // largest change of a sweep [m]
  constexpr int kMaxSweeps = 20000;
  double mean = 0;
  int count = 0;
  for (std::size_t k = 0; k < v.size(); ++k)
    if (known[k]) {
      mean += v[k];
      ++count;
    }
  if (count == 0 || count == static_cast<int>(v.size())) return;
  mean /= count;
  for (std::size_t k = 0; k < v.size(); ++k)
    if (!known[k]) v[k] = mean;
  for (int sweep = 0; sweep < kMaxSweeps; ++sweep) {
    double largest = 0;
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const std::size_t k = static_cast<std::size_t>(j) * nx + i;
        if (known[k]) continue;
        double sum = 0;
        int n = 0;
        auto add = [&](std::size_t neighbour) {
          sum += v[neighbour];
          ++n;
        };
        if (i > 0) add(k - 1);
        if (i + 1 < nx) add(k + 1);
        if (j > 0) add(k - nx);
        if (j + 1 < ny) add(k + nx);
        if (n == 0) continue;
        const double change = kOmega * (sum / n - v[k]);
        v[k] += change;
        largest = std::max(largest, std::abs(change));
      }
    if (largest < kConvergedM) break;
  }
}

// Linear interpolation weights between block centres b and b+1 for cell
// coordinate x, extended linearly beyond the first and last centre.
struct Lerp {
  int b = 0;
  double t = 0;
};
Lerp BlockLerp(double x, int block, int blocks) {
  if (blocks == 1) return {0, 0.0};
  const double u = (x - 0.5 * (block - 1)) / block;  // in block-centre units
  const int b = std::clamp(static_cast<int>(std::floor(u)), 0, blocks - 2);
  return {b, u - b};
}

// A polynomial trend over a grid of blocks, in coordinates scaled to
// [-1, 1] across the grid: 1, a, b (a plane) and a^2, ab, b^2 (quadratic).
struct BlockTrend {
  int bx = 1, by = 1;
  Eigen::VectorXd c;  // empty: no trend (0 everywhere)
  static Eigen::VectorXd Basis(int terms, double a, double b) {
    Eigen::VectorXd x(terms);
    x.head<3>() << 1.0, a, b;
    if (terms == 6) x.tail<3>() << a * a, a * b, b * b;
    return x;
  }
  Eigen::VectorXd BasisAt(int terms, std::size_t m) const {
    const double a = 2.0 * (static_cast<double>(m % bx) + 0.5) / bx - 1.0;
    const double b = 2.0 * (static_cast<double>(m / bx) + 0.5) / by - 1.0;
    return Basis(terms, a, b);
  }
  double At(std::size_t m) const { return c.size() ? BasisAt(static_cast<int>(c.size()), m).dot(c) : 0.0; }
};

// Least-squares fit of `terms` coefficients to value[m] over `blocks`;
// empty when the blocks do not determine them (too few, or all on a line).
Eigen::VectorXd FitBlockTrend(const BlockTrend& grid, int terms, const std::vector<double>& value,
                              const std::vector<std::size_t>& blocks) {
  // A plane through 3 blocks is what the model did before the quadratic;
  // a quadratic wants twice its terms, so that one block cannot bend it.
  const std::size_t least = terms == 3 ? 3 : 2 * static_cast<std::size_t>(terms);
  if (blocks.size() < least) return {};
  Eigen::MatrixXd design(blocks.size(), terms);
  Eigen::VectorXd rhs(blocks.size());
  for (std::size_t r = 0; r < blocks.size(); ++r) {
    design.row(r) = grid.BasisAt(terms, blocks[r]).transpose();
    rhs[r] = value[blocks[r]];
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(design.rows(), design.cols());
  constexpr double kRankThreshold = 1e-6;  // relative to the largest pivot: the coordinates are O(1)
  qr.setThreshold(kRankThreshold);
  qr.compute(design);
  if (qr.rank() < terms) return {};
  return qr.solve(rhs);
}

// The trend of the known blocks' values: a plane, or a quadratic surface
// where it predicts better. What the trend decides is the terrain where no
// ground was measured (the harmonic fill of the residual levels out away
// from the known blocks), so the two are judged on that: each of
// kFolds x kFolds squares of the block grid predicted from the known blocks
// outside it (spatial cross-validation), summing absolute errors. A hill's
// curvature makes a plane miss a hidden downhill corner by metres to tens
// of metres; a quadratic that only fits the known blocks better bends away
// beyond them and loses this test. Held-out squares of a quarter of the
// grid (2 x 2) were too harsh: an L of three quadrants did not predict the
// fourth's curvature on a hill scene where the quadratic was right.
BlockTrend ChooseBlockTrend(const std::vector<double>& value, const std::vector<std::size_t>& known, int bx, int by) {
  BlockTrend trend;
  trend.bx = bx;
  trend.by = by;
  constexpr int kFolds = 4;  // per side: a held-out square is a block or two of a 256 m city tile
  auto fold = [&](std::size_t m) {
    return (kFolds * static_cast<int>(m % bx)) / bx + kFolds * ((kFolds * static_cast<int>(m / bx)) / by);
  };
  auto cross_validated = [&](int terms) {
    double error = 0;
    bool tested = false;
    for (int q = 0; q < kFolds * kFolds; ++q) {
      std::vector<std::size_t> fit, held;
      for (std::size_t m : known) (fold(m) == q ? held : fit).push_back(m);
      if (held.empty()) continue;
      BlockTrend part = trend;
      part.c = FitBlockTrend(trend, terms, value, fit);
      if (!part.c.size()) return std::numeric_limits<double>::infinity();
      for (std::size_t m : held) error += std::abs(part.At(m) - value[m]);
      tested = true;
    }
    return tested ? error : std::numeric_limits<double>::infinity();
  };
  trend.c = FitBlockTrend(trend, 3, value, known);
  if (!trend.c.size()) return trend;
  constexpr int kQuadraticTerms = 6;
  if (cross_validated(kQuadraticTerms) < cross_validated(3)) {
    Eigen::VectorXd quadratic = FitBlockTrend(trend, kQuadraticTerms, value, known);
    if (quadratic.size()) trend.c = quadratic;
  }
  return trend;
}

}  // namespace

std::vector<float> GroundSurface(const std::vector<float>& h, int nx, int ny, int radius_cells, float max_rise_m) {
  CheckGrid(h, nx, ny);
  if (radius_cells < 1) throw Error("dense", "ground radius", std::to_string(radius_cells) + " cells must be >= 1");
  if (!(max_rise_m >= 0))
    throw Error("dense", "fill_ground_max_rise_m", std::to_string(max_rise_m) + " must be >= 0 (0 = off)");
  // A flat square opening that must lie within the grid keeps a plane only
  // where the squares fit: near an uphill edge it drops to the plane's
  // height 2r downhill. Opening the heights less their trend plane leaves
  // little slope to lose. The trend is the plane under the surface: fitted
  // to all measured cells, then again and again to the cells at or below
  // the last fit (buildings and trees fall out within a few rounds).
  constexpr int kTrendRounds = 6;
  std::vector<std::size_t> below;
  for (std::size_t k = 0; k < h.size(); ++k)
    if (std::isfinite(h[k])) below.push_back(k);
  std::optional<CellPlane> trend;
  for (int round = 0; round < kTrendRounds; ++round) {
    const std::optional<CellPlane> fit = FitPlane(h, nx, below);
    if (!fit) break;
    trend = fit;
    std::vector<std::size_t> next;
    for (std::size_t k : below)
      if (h[k] <= trend->At(static_cast<double>(k % nx), static_cast<double>(k / nx))) next.push_back(k);
    below.swap(next);
  }
  std::vector<float> trend_m(h.size(), 0.0f), detrended(h.size());
  for (std::size_t k = 0; k < h.size(); ++k) {
    if (trend) trend_m[k] = static_cast<float>(trend->At(static_cast<double>(k % nx), static_cast<double>(k / nx)));
    detrended[k] = h[k] - trend_m[k];
  }
  std::vector<float> opened = Opening(detrended, nx, ny, radius_cells, WindowEdge::kShift);
  if (max_rise_m > 0) {
    // Where the ground is hidden (streets between tall buildings seen
    // obliquely), a square of the opening can hold roofs only, and the
    // opening then takes the lowest roof for ground. The opening of twice
    // the radius reaches ground seen further away; where the narrow one
    // stands more than max_rise_m above it, no ground was measured in reach.
    const std::vector<float> wide = Opening(detrended, nx, ny, 2 * radius_cells, WindowEdge::kShift);
    for (std::size_t k = 0; k < h.size(); ++k)
      if (!(opened[k] - wide[k] <= max_rise_m)) opened[k] = kNan;
  }
  for (std::size_t k = 0; k < h.size(); ++k) opened[k] += trend_m[k];
  return opened;
}

std::vector<float> TerrainModel(const std::vector<float>& h, const std::vector<float>& ground, int nx, int ny,
                                const HoleFillGrid& o, int* trend_terms) {
  CheckGrid(h, nx, ny);
  if (ground.size() != h.size()) throw Error("dense", "ground surface", "size differs from the height grid's");
  const int block = o.terrain_block_cells;
  if (block < 2) throw Error("dense", "terrain block", std::to_string(block) + " cells must be >= 2");
  const int bx = (nx + block - 1) / block, by = (ny + block - 1) / block;
  std::vector<std::vector<std::size_t>> members(static_cast<std::size_t>(bx) * by);
  for (std::size_t k = 0; k < h.size(); ++k)
    if (std::isfinite(h[k]) && std::isfinite(ground[k]) && h[k] - ground[k] <= o.ground_tolerance_m)
      members[(k / nx / block) * bx + (k % nx) / block].push_back(k);
  std::vector<double> centre(members.size(), 0.0);
  std::vector<std::uint8_t> known(members.size(), 0);
  for (int b = 0; b < by; ++b)
    for (int a = 0; a < bx; ++a) {
      const std::size_t m = static_cast<std::size_t>(b) * bx + a;
      if (members[m].empty()) continue;
      // The nominal centre, also for a partial block at the grid's edge.
      const double ci = a * block + 0.5 * (block - 1), cj = b * block + 0.5 * (block - 1);
      // A plane needs cells spread over the block: a few noisy cells in a
      // corner would tilt it, and the centre can be half a block away.
      constexpr std::size_t kMinPlaneCells = 8;
      const std::optional<CellPlane> plane =
          members[m].size() >= kMinPlaneCells ? FitPlane(h, nx, members[m]) : std::nullopt;
      if (plane) {
        centre[m] = plane->At(ci, cj);
      } else {
        std::vector<double> z;
        for (std::size_t k : members[m]) z.push_back(h[k]);
        centre[m] = Quantile(z, 0.5);
      }
      known[m] = 1;
    }
  if (std::find(known.begin(), known.end(), 1) == known.end()) return std::vector<float>(h.size(), kNan);
  // Blocks without ground follow the trend of the known centres, plus the
  // harmonic interpolation of what the known ones leave: a hidden stretch
  // of a hillside keeps the hill's slope instead of levelling out.
  std::vector<std::size_t> known_blocks;
  for (std::size_t m = 0; m < known.size(); ++m)
    if (known[m]) known_blocks.push_back(m);
  const BlockTrend block_trend = ChooseBlockTrend(centre, known_blocks, bx, by);
  if (trend_terms) *trend_terms = static_cast<int>(block_trend.c.size());
  auto trend_at = [&](std::size_t m) { return block_trend.At(m); };
  for (std::size_t m = 0; m < centre.size(); ++m) centre[m] -= trend_at(m);
  HarmonicFill(centre, known, bx, by);
  for (std::size_t m = 0; m < centre.size(); ++m) centre[m] += trend_at(m);
  std::vector<float> terrain(h.size());
  for (int j = 0; j < ny; ++j) {
    const Lerp v = BlockLerp(j, block, by);
    for (int i = 0; i < nx; ++i) {
      const Lerp u = BlockLerp(i, block, bx);
      auto at = [&](int a, int b) { return centre[static_cast<std::size_t>(std::min(b, by - 1)) * bx + std::min(a, bx - 1)]; };
      const double low = (1 - u.t) * at(u.b, v.b) + u.t * at(u.b + 1, v.b);
      const double high = (1 - u.t) * at(u.b, v.b + 1) + u.t * at(u.b + 1, v.b + 1);
      terrain[static_cast<std::size_t>(j) * nx + i] = static_cast<float>((1 - v.t) * low + v.t * high);
    }
  }
  return terrain;
}

GroundModel GroundModelOf(const std::vector<float>& h, int nx, int ny, const HoleFillGrid& o) {
  GroundModel model;
  model.ground_m = GroundSurface(h, nx, ny, o.ground_radius_cells, o.ground_max_rise_m);
  model.terrain_m = TerrainModel(h, model.ground_m, nx, ny, o, &model.terrain_trend_terms);
  model.seen_hole_base_m = Opening(h, nx, ny, o.ground_radius_cells, WindowEdge::kClip);
  return model;
}

namespace {

// Whether cell k can be part of a roof's hole: a hole (NaN in `h`), and not
// `occluded` unless roof_rim_occluded.
bool RoofHoleCandidate(const std::vector<float>& h, const std::vector<std::uint8_t>* occluded,
                       const HoleFillGrid& o, std::size_t k) {
  return !std::isfinite(h[k]) && (o.roof_rim_occluded || !(occluded && (*occluded)[k]));
}

// Per cell, 1 where it belongs to a roof's hole: a piece of 4-connected
// hole cells (RoofHoleCandidate) of which at least
// roof_rim_fraction of the measured cells bordering it lie more than
// roof_rim_min_m above the ground (`above`). Each piece is walked once, each
// of its rim cells counted once. All 0 when the rule is off.
std::vector<std::uint8_t> RoofHoles(const std::vector<float>& h, const std::vector<float>& above,
                                    const std::vector<std::uint8_t>* occluded, int nx, int ny,
                                    const HoleFillGrid& o) {
  std::vector<std::uint8_t> roof_hole(h.size(), 0);
  if (o.roof_rim_fraction <= 0) return roof_hole;
  auto hole = [&](std::size_t k) { return RoofHoleCandidate(h, occluded, o, k); };
  std::vector<std::uint8_t> visited(h.size(), 0);
  std::vector<int> rim_of(h.size(), -1);  // the piece (its seed) a rim cell was last counted for
  std::vector<std::size_t> stack, members;
  for (std::size_t seed = 0; seed < h.size(); ++seed) {
    if (visited[seed] || !hole(seed)) continue;
    const int id = static_cast<int>(seed);
    visited[seed] = 1;
    stack.assign(1, seed);
    members.clear();
    int rim = 0, raised = 0;
    while (!stack.empty()) {
      const std::size_t k = stack.back();
      stack.pop_back();
      members.push_back(k);
      ForEachNeighbour4(k, nx, ny, [&](std::size_t n) {
        if (std::isfinite(h[n])) {
          if (rim_of[n] == id) return;
          rim_of[n] = id;
          ++rim;
          raised += above[n] > o.roof_rim_min_m ? 1 : 0;
        } else if (!visited[n] && hole(n)) {
          visited[n] = 1;
          stack.push_back(n);
        }
      });
    }
    if (rim > 0 && raised >= o.roof_rim_fraction * rim)
      for (std::size_t k : members) roof_hole[k] = 1;
  }
  return roof_hole;
}

// Marks in `roof_hole` each further candidate cell (RoofHoleCandidate)
// enclosed by a roof: marching from it along each of the 8 grid directions,
// every ray meets a measured cell within max_reach_cells, and all but one
// of those first cells lie more than
// roof_rim_min_m above the ground (`above`). Unlike RoofHoles' pieces, this
// does not depend on what the hole connects to: a roof's hole joined
// through hidden cells to the ground behind a tower beyond the roof's edge
// is one piece with a rim mostly of ground, yet its cells inside the roof
// are enclosed. A street between two roofs is not: its rays along the street
// meet the ground, or nothing within reach.
void MarkEnclosedByRoof(const std::vector<float>& h, const std::vector<float>& above,
                        const std::vector<std::uint8_t>* occluded, int nx, int ny, const HoleFillGrid& o,
                        std::vector<std::uint8_t>& roof_hole) {
  if (!o.roof_enclosed) return;
  constexpr int kDirections[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}};
  constexpr int kGroundAllowed = 1;  // one ray may leave through a gap in the roof's rim
  const int reach = o.max_reach_cells;
  tbb::parallel_for(0, ny, [&](int j) {
    for (int i = 0; i < nx; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * nx + i;
      if (roof_hole[k] || !RoofHoleCandidate(h, occluded, o, k)) continue;
      int ground = 0;
      bool all_met = true;
      for (const auto& d : kDirections) {
        bool met = false;
        for (int t = 1; t <= reach && !met; ++t) {
          const int a = i + t * d[0], b = j + t * d[1];
          if (a < 0 || b < 0 || a >= nx || b >= ny) break;
          const std::size_t n = static_cast<std::size_t>(b) * nx + a;
          if (!std::isfinite(h[n])) continue;
          met = true;
          ground += above[n] > o.roof_rim_min_m ? 0 : 1;
        }
        if (!met || ground > kGroundAllowed) {
          all_met = false;
          break;
        }
      }
      if (all_met) roof_hole[k] = 1;  // each row writes only its own cells
    }
  });
}

void CheckFillInputs(const std::vector<float>& h, int nx, int ny, const HoleFillGrid& o, const GroundModel& model,
                     const std::vector<std::uint8_t>* occluded) {
  CheckGrid(h, nx, ny);
  if (o.radius_cells < 1) throw Error("dense", "fill radius", std::to_string(o.radius_cells) + " cells must be >= 1");
  if (o.max_reach_cells < o.radius_cells)
    throw Error("dense", "fill reach", std::to_string(o.max_reach_cells) + " cells must be >= the fill radius");
  if (!(o.roof_rim_fraction >= 0 && o.roof_rim_fraction <= 1))
    throw Error("dense", "fill_roof_rim_fraction", std::to_string(o.roof_rim_fraction) + " must be in [0, 1] (0 = off)");
  if (model.terrain_m.size() != h.size() || model.seen_hole_base_m.size() != h.size())
    throw Error("dense", "ground model", "size differs from the height grid's");
  if (occluded && occluded->size() != h.size()) throw Error("dense", "occluded", "size differs from the height grid's");
}

// What every pass of FillHoles reads: the options, the ground model, the
// occlusion mask, which cells lie within reach of a measured one, and which
// holes belong to a roof.
struct FillContext {
  const HoleFillGrid& o;
  const GroundModel& model;
  const std::vector<std::uint8_t>* occluded;
  const std::vector<float>& in_reach;
  const std::vector<std::uint8_t>& roof_hole;
};

// The lowest heights above the seen-hole base within one pass's radius `r`:
// over every measured cell, and over the raised (roof) cells alone.
struct PassMinima {
  int r;
  const std::vector<float>& low_all;
  const std::vector<float>& low_raised;
};

// Fills hole cell k if this pass reaches it and returns true; false leaves
// it open for a wider pass.
bool FillCell(const FillContext& c, const PassMinima& pass, std::size_t k, std::vector<float>& h, FillRule* rule) {
  const HoleFillGrid& o = c.o;
  const std::vector<float>& base = c.model.seen_hole_base_m;
  const std::vector<float>& terrain = c.model.terrain_m;
  const bool hidden = c.occluded && (*c.occluded)[k];
  const bool raised_in_reach = c.roof_hole[k] && std::isfinite(pass.low_raised[k]);
  // Occluded cells of a roof's hole wait for the roof to come in reach.
  if (hidden && c.roof_hole[k] && !raised_in_reach && pass.r < o.max_reach_cells) return false;
  const bool ground = hidden && !raised_in_reach;
  const std::vector<float>& low = raised_in_reach ? pass.low_raised : pass.low_all;
  if (ground ? !std::isfinite(terrain[k]) || !std::isfinite(c.in_reach[k])
             : !std::isfinite(low[k]) || !std::isfinite(base[k])) {
    return false;
  }
  // "Ground" is judged above the opening. Where the opening is uphill
  // ground, a low roof can pass for ground and its hole takes the
  // terrain: judged above the terrain instead, the streets between a
  // hillside's tall buildings, whose nearest measured cells are all
  // roofs, kept the opening's height (decision D-102; D-106 is the
  // rejected alternative). Without a terrain model at the cell a
  // seen hole keeps the opening plus its lowest height.
  const bool seen_ground = o.seen_ground_takes_terrain && !ground && !raised_in_reach &&
                           low[k] <= o.roof_rim_min_m && std::isfinite(terrain[k]);
  const bool far_raised = o.far_raised_takes_ground && !ground && !raised_in_reach && pass.r > o.radius_cells &&
                          low[k] > o.roof_rim_min_m;
  // Seen ground and the far-raised cell's ground take the terrain model,
  // which keeps a hillside's slope; the plain opening there is the
  // highest of the lowest heights around (uphill ground), and for the
  // far-raised cell the lowest roof in reach.
  const float terrain_or_base = std::isfinite(terrain[k]) ? terrain[k] : base[k];
  h[k] = ground ? terrain[k] : (far_raised || seen_ground) ? terrain_or_base : base[k] + low[k];
  *rule = ground            ? FillRule::kOccludedGround
          : raised_in_reach ? FillRule::kRoofHole
          : seen_ground     ? FillRule::kSeenGround
          : far_raised      ? FillRule::kFarRaised
                            : FillRule::kSeenHole;
  return true;
}

}  // namespace

std::vector<std::uint8_t> FillHoles(std::vector<float>& h, int nx, int ny, const HoleFillGrid& o,
                                    const GroundModel& model, const std::vector<std::uint8_t>* occluded,
                                    std::vector<FillRule>* rules) {
  CheckFillInputs(h, nx, ny, o, model, occluded);
  std::vector<std::uint8_t> filled(h.size(), 0);
  if (rules) rules->assign(h.size(), FillRule::kMatched);
  // Heights of the measured cells above the base of seen holes.
  const std::vector<float>& base = model.seen_hole_base_m;
  std::vector<float> above(h.size());
  for (std::size_t k = 0; k < h.size(); ++k) above[k] = h[k] - base[k];
  // Occluded ground takes the terrain only within the largest reach of a
  // measured cell, like every other hole: the terrain model spans the whole
  // grid, but beyond the reach nothing was measured to fill from.
  std::vector<float> in_reach;
  if (occluded) {
    std::vector<float> measured(h.size());
    for (std::size_t k = 0; k < h.size(); ++k) measured[k] = std::isfinite(h[k]) ? 0.0f : NAN;
    in_reach = MinFilter(measured, nx, ny, o.max_reach_cells, WindowEdge::kClip);
  }
  // A roof's holes are filled from the raised cells alone; the raised
  // cells' minimum is only taken when there is such a hole.
  std::vector<std::uint8_t> roof_hole = RoofHoles(h, above, occluded, nx, ny, o);
  MarkEnclosedByRoof(h, above, occluded, nx, ny, o, roof_hole);
  std::vector<float> above_raised;
  if (std::find(roof_hole.begin(), roof_hole.end(), 1) != roof_hole.end()) {
    above_raised.assign(h.size(), kNan);
    for (std::size_t k = 0; k < h.size(); ++k)
      if (above[k] > o.roof_rim_min_m) above_raised[k] = above[k];
  }
  const FillContext context{o, model, occluded, in_reach, roof_hole};
  // Each pass fills what a square of this radius reaches; the radius
  // doubles up to the largest reach.
  for (int r = o.radius_cells;; r = std::min(2 * r, o.max_reach_cells)) {
    const std::vector<float> low_all = MinFilter(above, nx, ny, r, WindowEdge::kClip);
    const std::vector<float> low_raised =
        above_raised.empty() ? std::vector<float>() : MinFilter(above_raised, nx, ny, r, WindowEdge::kClip);
    const PassMinima pass{r, low_all, low_raised};
    bool open = false;
    for (std::size_t k = 0; k < h.size(); ++k) {
      if (std::isfinite(h[k])) continue;  // measured, or filled by an earlier pass
      FillRule rule;
      if (!FillCell(context, pass, k, h, &rule)) {
        open = true;
        continue;
      }
      filled[k] = 1;
      if (rules) (*rules)[k] = rule;
    }
    if (!open || r >= o.max_reach_cells) break;
  }
  return filled;
}

std::size_t RemoveFloatingPatches(std::vector<float>& h, int nx, int ny, const std::vector<float>& terrain,
                                  const FloatingPatchOptions& o) {
  CheckGrid(h, nx, ny);
  if (terrain.size() != h.size()) throw Error("dense", "terrain", "size differs from the height grid's");
  if (o.max_cells < 0)
    throw Error("dense", "floating_patch_max_m2", std::to_string(o.max_cells) + " cells must be >= 0 (0 = off)");
  if (!(o.min_rise_m >= 0)) throw Error("dense", "floating_patch_min_rise_m", std::to_string(o.min_rise_m) + " must be >= 0");
  if (o.max_cells == 0) return 0;
  std::vector<std::uint8_t> visited(h.size(), 0);
  std::vector<std::size_t> stack, members;
  std::size_t removed = 0;
  for (std::size_t seed = 0; seed < h.size(); ++seed) {
    if (visited[seed] || !std::isfinite(h[seed])) continue;
    visited[seed] = 1;
    stack.assign(1, seed);
    members.clear();
    bool floating = true;
    while (!stack.empty()) {
      const std::size_t k = stack.back();
      stack.pop_back();
      members.push_back(k);
      // NaN terrain compares false: no terrain, no evidence of floating.
      floating = floating && h[k] > terrain[k] + o.min_rise_m;
      ForEachNeighbour4(k, nx, ny, [&](std::size_t n) {
        if (!visited[n] && std::isfinite(h[n]) && std::abs(h[n] - h[k]) < o.smooth_step_m) {
          visited[n] = 1;
          stack.push_back(n);
        }
      });
    }
    if (!floating || members.size() >= static_cast<std::size_t>(o.max_cells)) continue;
    for (std::size_t k : members) h[k] = kNan;
    removed += members.size();
  }
  return removed;
}

HoleFillGrid HoleFillOptions::OnGrid(double cell_m) const {
  auto cells_of = [&](double m) { return std::max(1, static_cast<int>(std::lround(m / cell_m))); };
  HoleFillGrid g;
  g.radius_cells = cells_of(radius_m);
  g.max_reach_cells = cells_of(max_reach_m);
  g.ground_radius_cells = cells_of(ground_radius_m);
  g.ground_tolerance_m = static_cast<float>(ground_tolerance_m);
  g.ground_max_rise_m = static_cast<float>(ground_max_rise_m);
  g.terrain_block_cells = terrain_block_cells;
  g.roof_rim_fraction = static_cast<float>(roof_rim_fraction);
  g.roof_rim_min_m = static_cast<float>(roof_rim_min_m);
  g.roof_rim_occluded = roof_rim_occluded;
  g.roof_enclosed = roof_enclosed;
  g.far_raised_takes_ground = far_raised_takes_ground;
  g.seen_ground_takes_terrain = seen_ground_takes_terrain;
  return g;
}

void HoleFillOptions::Check() const {
  CheckOptionRanges(*this, "dense");
  if (!(max_reach_m >= radius_m))
    throw Error("dense", "max_fill_reach_m", FormatDouble(max_reach_m) + " must be >= fill_radius_m " + FormatDouble(radius_m));
}

}  // namespace skyfall
