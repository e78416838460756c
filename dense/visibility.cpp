#include "dense/sweep.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace skyfall {
namespace dense_detail {

// Per view (ENU directions toward the cameras), the height above which each
// cell of `surface_m` is seen (VisibleAbove, past `near_cells`), less
// `tolerance_m`: what the visibility pass and the step decision count as seen.
std::vector<std::vector<float>> SeenAbove(const HeightGrid& g, const std::vector<float>& surface_m,
                                          const std::vector<Eigen::Vector3d>& to_cameras, double floor_m,
                                          double tolerance_m, int near_cells) {
  std::vector<std::vector<float>> seen_above(to_cameras.size());
  tbb::parallel_for(0, static_cast<int>(to_cameras.size()), [&](int v) {
    seen_above[v] = VisibleAbove(g, surface_m, to_cameras[v], floor_m, near_cells);
    for (float& h : seen_above[v]) h -= static_cast<float>(tolerance_m);
  });
  return seen_above;
}

}  // namespace dense_detail

std::vector<float> VisibleAbove(const HeightGrid& g, const std::vector<float>& surface_m,
                                const Eigen::Vector3d& to_camera, double floor_m, int near_cells, bool edge_hides) {
  if (surface_m.size() != static_cast<std::size_t>(g.nx) * g.ny)
    throw Error("dense", "surface", "size " + std::to_string(surface_m.size()) + " is not nx*ny");
  const float lowest = -std::numeric_limits<float>::infinity();
  std::vector<float> out(surface_m.size(), lowest);
  const double horizontal = to_camera.head<2>().norm();
  if (!(horizontal > 1e-9 * to_camera.norm()) || !(to_camera.z() > 0)) return out;  // straight down: nothing hides
  float top = lowest;
  for (float h : surface_m)
    if (std::isfinite(h)) top = std::max(top, h);
  if (!std::isfinite(top)) return out;
  // March toward the camera one cell at a time; the ray rises `rise` per step.
  const double step_i = to_camera.x() / horizontal, step_j = to_camera.y() / horizontal;
  const double rise = g.cell_m * to_camera.z() / horizontal;
  tbb::parallel_for(0, g.ny, [&](int j) {
    for (int i = 0; i < g.nx; ++i) {
      float best = lowest;
      for (int t = 1 + near_cells;; ++t) {
        const double drop = t * rise;
        if (top - drop <= best || top - drop < floor_m) break;  // nothing further can hide the cell
        const int a = static_cast<int>(std::lround(i + t * step_i)), b = static_cast<int>(std::lround(j + t * step_j));
        if (a < 0 || b < 0 || a >= g.nx || b >= g.ny) {
          if (edge_hides) best = static_cast<float>(top - drop);
          break;
        }
        const float h = surface_m[g.Index(a, b)];
        if (std::isfinite(h)) best = std::max(best, static_cast<float>(h - drop));
      }
      out[g.Index(i, j)] = best;
    }
  });
  return out;
}

std::vector<std::uint8_t> OccludedAtGround(const HeightGrid& g, const std::vector<float>& surface_m,
                                           const std::vector<float>& terrain_m,
                                           const std::vector<Eigen::Vector3d>& to_cameras,
                                           const std::vector<std::array<int, 2>>& pairs, double tolerance_m,
                                           double floor_m, bool edge_hides) {
  const std::size_t cells = static_cast<std::size_t>(g.nx) * g.ny;
  if (surface_m.size() != cells || terrain_m.size() != cells)
    throw Error("dense", "surface", "size " + std::to_string(surface_m.size()) + " is not nx*ny");
  const int views = static_cast<int>(to_cameras.size());
  for (const auto& p : pairs)
    if (p[0] < 0 || p[1] < 0 || p[0] >= views || p[1] >= views)
      throw Error("dense", "pair", std::to_string(p[0]) + "-" + std::to_string(p[1]) + " names a view beyond the " +
                                       std::to_string(views) + " given");
  // Per view, the cells whose ground point it sees.
  std::vector<std::vector<std::uint8_t>> sees(to_cameras.size());
  for (int v = 0; v < views; ++v) {
    const std::vector<float> seen_above =
        VisibleAbove(g, surface_m, to_cameras[v], floor_m, 0, edge_hides);
    sees[v].resize(cells);
    for (std::size_t k = 0; k < cells; ++k) sees[v][k] = terrain_m[k] + tolerance_m >= seen_above[k] ? 1 : 0;
  }
  std::vector<std::uint8_t> seen_by_pair(cells, 0);
  for (const auto& p : pairs) {
    const std::vector<std::uint8_t>& a = sees[p[0]];
    const std::vector<std::uint8_t>& b = sees[p[1]];
    for (std::size_t k = 0; k < cells; ++k) seen_by_pair[k] |= a[k] & b[k];
  }
  std::vector<std::uint8_t> occluded(cells, 0);
  for (std::size_t k = 0; k < cells; ++k)
    occluded[k] = !std::isfinite(surface_m[k]) && std::isfinite(terrain_m[k]) && !seen_by_pair[k] ? 1 : 0;
  return occluded;
}

}  // namespace skyfall
