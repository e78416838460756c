#include "merge/ownership.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <unordered_map>

#include "core/error.h"

namespace skyfall {
namespace {

// A band along a tile boundary, in (across, along) coordinates: across is
// east for a boundary between columns, north for one between rows.
struct Band {
  bool between_columns = true;
  double across0_m = 0, along0_m = 0, cell_m = 0;
  int n_across = 0, n_along = 0;
};

// A tile's surface sampled at the band's cell centres.
std::vector<float> SampleBand(const SurfaceHeight& surface, const Band& band) {
  std::vector<float> h(static_cast<std::size_t>(band.n_across) * band.n_along);
  for (int l = 0; l < band.n_along; ++l) {
    for (int a = 0; a < band.n_across; ++a) {
      const double across = band.across0_m + (a + 0.5) * band.cell_m, along = band.along0_m + (l + 0.5) * band.cell_m;
      h[static_cast<std::size_t>(l) * band.n_across + a] =
          band.between_columns ? surface(across, along) : surface(along, across);
    }
  }
  return h;
}

// The line through the band (cut between across cells k - 1 and k, k in
// [1, n_across - 1]) of least summed disagreement, moving at most one cell
// sideways per cell along.
CutLine DecideLine(const SeamLineOptions& o, const Band& band, const std::vector<float>& first,
                   const std::vector<float>& second) {
  const int na = band.n_across, nl = band.n_along, positions = na - 1;
  std::vector<float> disagreement(first.size());
  for (std::size_t k = 0; k < first.size(); ++k) {
    const bool both = std::isfinite(first[k]) && std::isfinite(second[k]);
    disagreement[k] = both ? std::min(std::abs(first[k] - second[k]), static_cast<float>(o.max_step_m))
                           : static_cast<float>(o.max_step_m);
  }
  const int middle = na / 2;  // the core boundary
  // A cut between cells k - 1 (first tile) and k (second) costs the tiles'
  // disagreement on both cells plus the step it leaves in the merged
  // surface: where they agree on a wall, cutting along it would still put
  // the whole wall on the line.
  const float cap = static_cast<float>(o.max_step_m);
  auto cost = [&](int l, int k) {
    const std::size_t at = static_cast<std::size_t>(l) * na;
    const float* row = &disagreement[at];
    const float step = std::abs(first[at + k - 1] - second[at + k]);
    return std::max(row[k - 1], row[k]) + (std::isfinite(step) ? std::min(step, cap) : cap) +
           o.centre_pull_m * std::abs(k - middle);
  };
  std::vector<double> total(positions), next(positions);
  std::vector<std::int8_t> came_from(static_cast<std::size_t>(nl) * positions, 0);
  for (int k = 1; k <= positions; ++k) total[k - 1] = cost(0, k);
  for (int l = 1; l < nl; ++l) {
    for (int k = 1; k <= positions; ++k) {
      double best = total[k - 1];
      std::int8_t from = 0;
      if (k > 1 && total[k - 2] + o.bend_m < best) best = total[k - 2] + o.bend_m, from = -1;
      if (k < positions && total[k] + o.bend_m < best) best = total[k] + o.bend_m, from = 1;
      next[k - 1] = best + cost(l, k);
      came_from[static_cast<std::size_t>(l) * positions + (k - 1)] = from;
    }
    std::swap(total, next);
  }
  CutLine line;
  line.along_start_m = band.along0_m;
  line.cell_m = band.cell_m;
  line.cut_m.resize(nl);
  int k = static_cast<int>(std::min_element(total.begin(), total.end()) - total.begin()) + 1;
  for (int l = nl - 1; l >= 0; --l) {
    line.cut_m[l] = band.across0_m + k * band.cell_m;
    k += came_from[static_cast<std::size_t>(l) * positions + (k - 1)];
  }
  return line;
}

// The highest opaque Gaussian centre per cell of `cell_m`; NaN where none.
SurfaceHeight SurfaceOfCentres(const GaussianCloud& cloud, double cell_m, double min_opacity) {
  auto key = [cell_m](double e, double n) {
    const auto i = static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(e / cell_m)));
    const auto j = static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(n / cell_m)));
    return (i << 32) ^ (j & 0xffffffffu);
  };
  auto top = std::make_shared<std::unordered_map<std::uint64_t, float>>();
  const float min_logit = static_cast<float>(std::log(min_opacity / (1.0 - min_opacity)));
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (cloud.opacity_logits[i] < min_logit) continue;
    const Eigen::Vector3f& p = cloud.means[i];
    auto [it, added] = top->emplace(key(p.x(), p.y()), p.z());
    if (!added) it->second = std::max(it->second, p.z());
  }
  return [top, key](double e, double n) {
    const auto it = top->find(key(e, n));
    return it == top->end() ? std::numeric_limits<float>::quiet_NaN() : it->second;
  };
}

// -1, 0 or +1: whether a point (across, along) lies past the line to the
// next cell, before the line to the previous one, or between them (a null
// line: straight, nothing crosses it).
int Crossing(const CutLine* to_next, const CutLine* to_previous, double across_m, double along_m) {
  if (to_next && across_m >= to_next->CutAt(along_m)) return 1;
  if (to_previous && across_m < to_previous->CutAt(along_m)) return -1;
  return 0;
}

}  // namespace

void SeamLineOptions::Check() const { CheckOptionRanges(*this, "merge", "seam_lines"); }

double CutLine::CutAt(double along_m) const {
  const double k = std::floor((along_m - along_start_m) / cell_m);
  return cut_m[static_cast<std::size_t>(std::clamp(k, 0.0, static_cast<double>(cut_m.size() - 1)))];
}

TileOwnership::TileOwnership(const TileGrid& grid) : grid_(grid) {}

Eigen::Vector2i TileOwnership::Owner(double east_m, double north_m) const {
  const Eigen::Vector2i core = grid_.Owner(east_m, north_m);
  Eigen::Vector2i out = core;
  auto line = [](const std::vector<CutLine>& lines, int index) -> const CutLine* {
    return index >= 0 && index < static_cast<int>(lines.size()) && !lines[index].cut_m.empty() ? &lines[index] : nullptr;
  };
  // Across the column boundaries of the core's row, then across the row
  // boundaries of the column so chosen: a function of the point alone, so
  // every point has exactly one owner, and near a corner the row is decided
  // by the line planned between the two tiles it chooses from (never
  // toward a tile that is missing: lines beside one are straight).
  const int row = core.y();
  out.x() += Crossing(core.x() + 1 < grid_.cols ? line(vertical_, row * (grid_.cols - 1) + core.x()) : nullptr,
                      core.x() > 0 ? line(vertical_, row * (grid_.cols - 1) + core.x() - 1) : nullptr, east_m, north_m);
  const int col = out.x();
  out.y() += Crossing(row + 1 < grid_.rows ? line(horizontal_, col * (grid_.rows - 1) + row) : nullptr,
                      row > 0 ? line(horizontal_, col * (grid_.rows - 1) + row - 1) : nullptr, north_m, east_m);
  return out;
}

std::size_t TileOwnership::lines() const {
  std::size_t n = 0;
  for (const auto* set : {&vertical_, &horizontal_})
    for (const CutLine& l : *set) n += !l.cut_m.empty();
  return n;
}

double TileOwnership::MeanDeviationM() const {
  double sum = 0;
  std::size_t cells = 0;
  auto add = [&](const std::vector<CutLine>& lines, bool between_columns) {
    for (std::size_t i = 0; i < lines.size(); ++i) {
      if (lines[i].cut_m.empty()) continue;
      const int lo = between_columns ? static_cast<int>(i % (grid_.cols - 1)) : static_cast<int>(i % (grid_.rows - 1));
      const double boundary = between_columns ? grid_.origin_m.x() + (lo + 1) * grid_.tile_m
                                              : grid_.origin_m.y() + (lo + 1) * grid_.tile_m;
      for (double c : lines[i].cut_m) sum += std::abs(c - boundary);
      cells += lines[i].cut_m.size();
    }
  };
  add(vertical_, true);
  add(horizontal_, false);
  return cells ? sum / cells : 0.0;
}

TileOwnership PlanSeamLines(const SeamLineOptions& options, const std::vector<TileSpec>& tiles,
                            const std::vector<SurfaceHeight>& surfaces) {
  options.Check();
  if (tiles.size() != surfaces.size()) throw Error("merge", "seam lines", "one surface per tile needed");
  if (tiles.empty()) return TileOwnership();
  TileOwnership out(tiles[0].grid);
  const TileGrid& g = out.grid_;
  const double half_width_m = options.band_fraction * g.overlap_m;
  const int half_cells = static_cast<int>(std::floor(half_width_m / options.cell_m));
  if (!options.enabled || half_cells < 1) return out;
  std::vector<int> at(static_cast<std::size_t>(g.cols) * g.rows, -1);
  for (std::size_t k = 0; k < tiles.size(); ++k) {
    const TileSpec& t = tiles[k];
    if (t.col >= 0 && t.col < g.cols && t.row >= 0 && t.row < g.rows)
      at[static_cast<std::size_t>(t.row) * g.cols + t.col] = static_cast<int>(k);
  }
  auto plan = [&](int first_index, int second_index, bool between_columns) {
    CutLine none;
    if (first_index < 0 || second_index < 0) return none;
    const TileSpec& first = tiles[first_index];
    const TileSpec& second = tiles[second_index];
    Band band;
    band.between_columns = between_columns;
    band.cell_m = options.cell_m;
    band.n_across = 2 * half_cells;
    const int axis = between_columns ? 0 : 1, along_axis = 1 - axis;
    const double boundary = first.core.max_m[axis];
    band.across0_m = boundary - half_cells * options.cell_m;
    // Along: the first tile's core, where both tiles reconstruct.
    const double lo = std::max({first.core.min_m[along_axis], first.extent.min_m[along_axis],
                                second.extent.min_m[along_axis]});
    const double hi = std::min({first.core.max_m[along_axis], first.extent.max_m[along_axis],
                                second.extent.max_m[along_axis]});
    band.along0_m = lo;
    band.n_along = static_cast<int>(std::ceil((hi - lo) / options.cell_m));
    if (band.n_along < 1) return none;
    return DecideLine(options, band, SampleBand(surfaces[first_index], band), SampleBand(surfaces[second_index], band));
  };
  auto index = [&](int col, int row) { return at[static_cast<std::size_t>(row) * g.cols + col]; };
  if (g.cols > 1) {
    out.vertical_.resize(static_cast<std::size_t>(g.rows) * (g.cols - 1));
    for (int row = 0; row < g.rows; ++row)
      for (int col = 0; col + 1 < g.cols; ++col)
        out.vertical_[static_cast<std::size_t>(row) * (g.cols - 1) + col] = plan(index(col, row), index(col + 1, row), true);
  }
  if (g.rows > 1) {
    out.horizontal_.resize(static_cast<std::size_t>(g.cols) * (g.rows - 1));
    for (int col = 0; col < g.cols; ++col)
      for (int row = 0; row + 1 < g.rows; ++row)
        out.horizontal_[static_cast<std::size_t>(col) * (g.rows - 1) + row] = plan(index(col, row), index(col, row + 1), false);
  }
  return out;
}

TileSource TilesInMemory(const std::vector<TileCloud>& tiles) {
  TileSource source;
  for (const TileCloud& t : tiles) source.specs.push_back(t.tile);
  source.visit = [&tiles](std::size_t k, const CloudUser& use) { use(tiles.at(k).cloud); };
  return source;
}

TileOwnership PlanSeamLinesOnCentres(const SeamLineOptions& options, const TileSource& tiles) {
  if (tiles.size() == 0) return TileOwnership();
  if (!options.enabled) return TileOwnership(tiles.specs[0].grid);
  constexpr double kSurfaceOpacity = 0.5;
  std::vector<SurfaceHeight> surfaces;
  for (std::size_t k = 0; k < tiles.size(); ++k)
    tiles.visit(k, [&](const GaussianCloud& cloud) {
      surfaces.push_back(SurfaceOfCentres(cloud, options.cell_m, kSurfaceOpacity));
    });
  return PlanSeamLines(options, tiles.specs, surfaces);
}

TileOwnership PlanSeamLinesOnCentres(const SeamLineOptions& options, const std::vector<TileCloud>& tiles) {
  return PlanSeamLinesOnCentres(options, TilesInMemory(tiles));
}

}  // namespace skyfall
