#include "dense/dense_cells.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall {

std::string DenseCellsPly(const HeightGrid& g) {
  std::size_t count = 0;
  for (float h : g.height_m) count += std::isfinite(h) ? 1 : 0;
  std::string out = "ply\nformat ascii 1.0\ncomment skyfall dense heights, ENU metres, one point per " +
                    std::to_string(g.cell_m) + " m cell\nelement vertex " + std::to_string(count) +
                    "\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\n"
                    "property uchar green\nproperty uchar blue\nproperty float matching_cost\nproperty uchar filled\nend_header\n";
  char line[160];
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = g.Index(i, j);
      if (!std::isfinite(g.height_m[k])) continue;
      std::snprintf(line, sizeof line, "%.3f %.3f %.3f %d %d %d %.4f %d\n", g.x0_m + i * g.cell_m,
                    g.y0_m + j * g.cell_m, g.height_m[k], g.rgb[k][0], g.rgb[k][1], g.rgb[k][2], g.cost[k],
                    g.filled[k]);
      out += line;
    }
  return out;
}

DenseCells ReadDenseCells(const std::string& path) {
  std::istringstream in(ReadTextFile(path));
  DenseCells cells;
  std::string line;
  std::size_t count = 0;
  while (std::getline(in, line) && line != "end_header") {
    const std::size_t at = line.find("one point per ");
    if (at != std::string::npos) cells.cell_m = std::stod(line.substr(at + 14));
    if (line.rfind("element vertex", 0) == 0) count = std::stoul(line.substr(15));
  }
  if (!(cells.cell_m > 0))
    throw Error("dense", path, "states no cell size (expected the dense.ply written by `skyfall dense`)");
  double x, y, z, cost;
  int r, g, b, filled;
  while (in >> x >> y >> z >> r >> g >> b >> cost >> filled) {
    cells.points.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    cells.colours.emplace_back(r / 255.0f, g / 255.0f, b / 255.0f);
    cells.filled.push_back(filled != 0);
  }
  if (cells.points.size() != count)
    throw Error("dense", path, "holds " + std::to_string(cells.points.size()) + " cells, its header says " +
                                   std::to_string(count) + " (truncated?)");
  return cells;
}

}  // namespace skyfall
