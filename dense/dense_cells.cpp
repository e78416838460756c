#include "dense/dense_cells.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall {

namespace {

// The properties of a cell, in the file's order.
constexpr const char* kProperties =
    "property double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\n"
    "property uchar blue\nproperty float matching_cost\nproperty uchar filled\nproperty uchar fill_rule\n"
    "property uchar views\nproperty float terrain_z\n";

}  // namespace

std::string DenseCellsPly(const HeightGrid& g) {
  std::size_t count = 0;
  for (float h : g.height_m) count += std::isfinite(h) ? 1 : 0;
  std::string out = "ply\nformat ascii 1.0\ncomment skyfall dense heights, ENU metres, one point per " +
                    std::to_string(g.cell_m) + " m cell\nelement vertex " + std::to_string(count) + "\n" +
                    kProperties + "end_header\n";
  char line[200];
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = g.Index(i, j);
      if (!std::isfinite(g.height_m[k])) continue;
      const int rule = g.fill_rule.empty() ? 0 : static_cast<int>(g.fill_rule[k]);
      const int views = g.views.empty() ? 0 : g.views[k];
      const float terrain = g.terrain_m.empty() ? NAN : g.terrain_m[k];
      std::snprintf(line, sizeof line, "%.3f %.3f %.3f %d %d %d %.4f %d %d %d %.3f\n", g.x0_m + i * g.cell_m,
                    g.y0_m + j * g.cell_m, g.height_m[k], g.rgb[k][0], g.rgb[k][1], g.rgb[k][2], g.cost[k],
                    g.filled[k], rule, views, terrain);
      out += line;
    }
  return out;
}

DenseCells ReadDenseCells(const std::string& path) {
  std::istringstream in(ReadTextFile(path));
  DenseCells cells;
  std::string line;
  std::size_t count = 0;
  std::vector<std::string> names;  // the properties, in the file's order
  while (std::getline(in, line) && line != "end_header") {
    const std::size_t at = line.find("one point per ");
    if (at != std::string::npos) cells.cell_m = std::stod(line.substr(at + 14));
    if (line.rfind("element vertex", 0) == 0) count = std::stoul(line.substr(15));
    if (line.rfind("property ", 0) == 0) names.push_back(line.substr(line.rfind(' ') + 1));
  }
  if (!(cells.cell_m > 0))
    throw Error("dense", path, "states no cell size (expected the dense.ply written by `skyfall dense`)");
  auto column = [&](const char* name) {
    const auto it = std::find(names.begin(), names.end(), name);
    return it == names.end() ? -1 : static_cast<int>(it - names.begin());
  };
  const int x = column("x"), y = column("y"), z = column("z"), red = column("red"), green = column("green"),
            blue = column("blue"), cost = column("matching_cost"), filled = column("filled"),
            rule = column("fill_rule"), views = column("views"), terrain = column("terrain_z");
  for (int c : {x, y, z, red, green, blue, filled})
    if (c < 0) throw Error("dense", path, "lacks a property of the dense cells (x y z red green blue filled)");
  std::vector<double> v(names.size());
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    const char* p = line.c_str();
    for (double& value : v) {
      char* end = nullptr;
      value = std::strtod(p, &end);  // reads "nan": a cell without terrain
      if (end == p) throw Error("dense", path, "has a short cell line: '" + line + "'");
      p = end;
    }
    cells.points.emplace_back(static_cast<float>(v[x]), static_cast<float>(v[y]), static_cast<float>(v[z]));
    cells.colours.emplace_back(v[red] / 255.0f, v[green] / 255.0f, v[blue] / 255.0f);
    cells.filled.push_back(v[filled] != 0);
    if (cost >= 0) cells.cost.push_back(static_cast<float>(v[cost]));
    if (rule >= 0) cells.fill_rule.push_back(static_cast<FillRule>(static_cast<int>(v[rule])));
    if (views >= 0) cells.views.push_back(static_cast<std::uint8_t>(v[views]));
    if (terrain >= 0) cells.terrain_m.push_back(static_cast<float>(v[terrain]));
  }
  if (cells.points.size() != count)
    throw Error("dense", path, "holds " + std::to_string(cells.points.size()) + " cells, its header says " +
                                   std::to_string(count) + " (truncated?)");
  return cells;
}

}  // namespace skyfall
