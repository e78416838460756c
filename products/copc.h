// The octree of a Cloud Optimized Point Cloud (COPC 1.0): a cube around the
// cloud, split into octants, each node holding a thinned share of the points
// inside it (one point per cell of a grid of kCopcGridCells^3 over the node)
// and its children the rest, so that a viewer reads coarse nodes first and
// finer ones only where it looks. Every point is in exactly one node.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace skyfall {

// Cells per axis of a node's thinning grid: the node's point spacing is its
// width over this.
constexpr int kCopcGridCells = 128;
// A node with at most this many points keeps them all (a leaf). Below LASzip's
// default chunk of 50,000 points, so every node is one ordinary chunk.
constexpr std::size_t kCopcMaxNodePoints = 40000;

// The octree's cube in the file's real coordinates.
struct CopcCube {
  std::array<double, 3> center{};
  double halfsize = 0;
};

// A node: its key (level, x, y, z as COPC counts them) and its points (indices into
// the cloud given to BuildCopcOctree), in the order they are stored.
struct CopcNode {
  std::array<std::int32_t, 4> key{};
  std::vector<std::uint32_t> points;
};

// The cube: centred on the bounds of `xyz`, its half-size half the largest
// extent plus one storage step (so that no point lies on the far face), at
// least one metre.
CopcCube CopcCubeAround(const std::vector<std::array<double, 3>>& xyz, double step_m);

// Nodes in breadth-first order (the root first), none empty. Within a node
// the points follow a Morton order of their position, which keeps LAZ's
// coordinate differences small.
std::vector<CopcNode> BuildCopcOctree(const std::vector<std::array<double, 3>>& xyz, const CopcCube& cube);

// All of `xyz` along one Morton curve over the cube (plain LAZ's chunk order).
std::vector<std::uint32_t> MortonOrder(const std::vector<std::array<double, 3>>& xyz, const CopcCube& cube);

}  // namespace skyfall
