#include "products/copc.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <utility>

namespace skyfall {
namespace {

constexpr int kMaxLevel = 24;  // cells far below a millimetre step at any city size

// Bounds of the node `key` within the cube.
struct Box {
  std::array<double, 3> min;
  double width;
};

Box NodeBox(const CopcCube& cube, const std::array<std::int32_t, 4>& key) {
  const double width = 2 * cube.halfsize / std::ldexp(1.0, key[0]);
  Box b{};
  b.width = width;
  for (int a = 0; a < 3; ++a) b.min[a] = cube.center[a] - cube.halfsize + key[a + 1] * width;
  return b;
}

// Cell of `p` on a grid of `cells` per axis over `box`, clamped inside.
std::array<std::uint32_t, 3> Cell(const Box& box, const std::array<double, 3>& p, int cells) {
  std::array<std::uint32_t, 3> c{};
  for (int a = 0; a < 3; ++a) {
    const double t = std::floor((p[a] - box.min[a]) / box.width * cells);
    c[a] = static_cast<std::uint32_t>(std::clamp(t, 0.0, static_cast<double>(cells - 1)));
  }
  return c;
}

// Interleaves the low 21 bits of each axis.
std::uint64_t Morton(const std::array<std::uint32_t, 3>& c) {
  std::uint64_t code = 0;
  for (int bit = 0; bit < 21; ++bit) {
    for (int a = 0; a < 3; ++a) code |= std::uint64_t((c[a] >> bit) & 1u) << (3 * bit + a);
  }
  return code;
}

// Sorts a node's points along a Morton curve of a fine grid over the node.
void MortonSort(const Box& box, const std::vector<std::array<double, 3>>& xyz, std::vector<std::uint32_t>* points) {
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
  order.reserve(points->size());
  for (std::uint32_t i : *points) order.emplace_back(Morton(Cell(box, xyz[i], 1 << 20)), i);
  std::sort(order.begin(), order.end());
  for (std::size_t k = 0; k < order.size(); ++k) (*points)[k] = order[k].second;
}

}  // namespace

std::vector<std::uint32_t> MortonOrder(const std::vector<std::array<double, 3>>& xyz, const CopcCube& cube) {
  std::vector<std::uint32_t> order(xyz.size());
  for (std::uint32_t i = 0; i < order.size(); ++i) order[i] = i;
  MortonSort(NodeBox(cube, {0, 0, 0, 0}), xyz, &order);
  return order;
}

CopcCube CopcCubeAround(const std::vector<std::array<double, 3>>& xyz, double step_m) {
  CopcCube cube;
  if (xyz.empty()) {
    cube.halfsize = 1;
    return cube;
  }
  std::array<double, 3> lo, hi;
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  for (const auto& p : xyz) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], p[a]);
      hi[a] = std::max(hi[a], p[a]);
    }
  }
  double extent = 0;
  for (int a = 0; a < 3; ++a) {
    cube.center[a] = 0.5 * (lo[a] + hi[a]);
    extent = std::max(extent, hi[a] - lo[a]);
  }
  cube.halfsize = std::max(1.0, 0.5 * extent + step_m);
  return cube;
}

std::vector<CopcNode> BuildCopcOctree(const std::vector<std::array<double, 3>>& xyz, const CopcCube& cube) {
  std::vector<CopcNode> nodes;
  std::deque<CopcNode> queue;  // nodes whose points are not yet split
  CopcNode root{{0, 0, 0, 0}, {}};
  root.points.resize(xyz.size());
  for (std::uint32_t i = 0; i < root.points.size(); ++i) root.points[i] = i;
  if (!root.points.empty()) queue.push_back(std::move(root));

  while (!queue.empty()) {
    CopcNode node = std::move(queue.front());
    queue.pop_front();
    const Box box = NodeBox(cube, node.key);
    CopcNode out{node.key, {}};
    if (node.points.size() <= kCopcMaxNodePoints || node.key[0] >= kMaxLevel) {
      out.points = std::move(node.points);
    } else {
      // Keep the first point met in each grid cell (the input order decides,
      // so the result is reproducible); hand the others to the octants.
      std::vector<std::pair<std::uint64_t, std::uint32_t>> cells;
      cells.reserve(node.points.size());
      for (std::uint32_t i : node.points) cells.emplace_back(Morton(Cell(box, xyz[i], kCopcGridCells)), i);
      std::stable_sort(cells.begin(), cells.end(),
                       [](const auto& a, const auto& b) { return a.first < b.first; });
      std::array<CopcNode, 8> children;
      for (int o = 0; o < 8; ++o) {
        children[o].key = {node.key[0] + 1, 2 * node.key[1] + (o & 1), 2 * node.key[2] + ((o >> 1) & 1),
                           2 * node.key[3] + ((o >> 2) & 1)};
      }
      for (std::size_t k = 0; k < cells.size(); ++k) {
        const std::uint32_t i = cells[k].second;
        if (k == 0 || cells[k].first != cells[k - 1].first) {
          out.points.push_back(i);
          continue;
        }
        const auto half = Cell(box, xyz[i], 2);
        children[half[0] | (half[1] << 1) | (half[2] << 2)].points.push_back(i);
      }
      for (auto& child : children) {
        if (!child.points.empty()) queue.push_back(std::move(child));
      }
    }
    MortonSort(box, xyz, &out.points);
    nodes.push_back(std::move(out));
  }
  return nodes;
}

}  // namespace skyfall
