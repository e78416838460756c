// Which tile's Gaussians the merge keeps where. Straight core boundaries put
// a seam wherever two independent reconstructions disagree there (a roof
// edge one tile places half a metre further out, a tree one tile missed),
// and the merged surface steps along the boundary. Orthomosaics route their
// seam lines along streets rather than through buildings; here each tile
// boundary gets a cut line inside the overlap band that follows where the
// two tiles' surfaces agree: the least total cost over the line (the tiles'
// disagreement beside the cut plus the height step the cut leaves), found
// by dynamic programming along it, moving at most one cell sideways per
// cell along.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "core/gaussians.h"
#include "core/option_range.h"
#include "core/tile.h"

namespace skyfall {

struct TileCloud {
  TileSpec tile;        // grid, core, extent and the frame the cloud is in
  GaussianCloud cloud;  // in the ENU frame at tile.enu_origin
};

// Tiles as the merge streams them: their specs, and tile k's Gaussians (in
// the frame at specs[k].enu_origin) handed to `use` for one call, so that a
// reader may load them from disk for that call only: memory then holds one
// tile, whatever the city's size.
using CloudUser = std::function<void(const GaussianCloud& cloud)>;
struct TileSource {
  std::vector<TileSpec> specs;
  std::function<void(std::size_t k, const CloudUser& use)> visit;
  std::size_t size() const { return specs.size(); }
};
// A source over tiles in memory (which must outlive it).
TileSource TilesInMemory(const std::vector<TileCloud>& tiles);

// A tile's surface height at a ground point of the tiles' shared frame
// [m, any datum common to all tiles]; NaN where the tile has no surface.
using SurfaceHeight = std::function<float(double east_m, double north_m)>;

struct SeamLineOptions {
  bool enabled = true;          // false: the straight core boundaries
  double cell_m = 0.5;          // [m] cell of the height maps and of the line
  // Lines stay within this fraction of the overlap margin of the core
  // boundary: a tile is least reliable at its extent's edge, where its
  // windows and views run out.
  double band_fraction = 0.5;
  // [m] disagreements are capped here, and a cell only one tile has costs
  // this much: one wrong building does not outweigh a whole street.
  double max_step_m = 5.0;
  // [m] added per cell the line moves sideways: where the tiles agree on a
  // flat surface the line stays straight on the core boundary (beside a
  // wall it may step off it, since a cut along a wall leaves the wall's
  // height as the step).
  double bend_m = 0.02;
  // [m] added per cell along for each cell the line is off the boundary:
  // a detour ends where the disagreement does.
  double centre_pull_m = 0.005;
  void Check() const;           // throws Error("merge", field, ...)
};
template <class IO> void Visit(IO& io, SeamLineOptions& o) {
  io("enabled", o.enabled,
     "Cut between tiles along seam lines where their DSMs agree; off: the straight core boundaries");
  io("cell_m", o.cell_m,
     "Cell of the height maps and of the seam line", range::Above(0));
  io("band_fraction", o.band_fraction,
     "Seam lines stay within this fraction of the overlap margin of the core boundary", range::In(0, 1));
  io("max_step_m", o.max_step_m,
     "Height disagreements are capped at this, and a cell only one tile covers costs this much", range::Above(0));
  io("bend_m", o.bend_m,
     "Cost added per cell the line moves sideways, so that it stays straight where the tiles agree", range::AtLeast(0));
  io("centre_pull_m", o.centre_pull_m,
     "Cost added per cell along the line for each cell it is off the core boundary, so that a detour ends where the "
     "disagreement does", range::Above(0));
}

// A cut line along one tile boundary: for each cell along the boundary, the
// coordinate across it where ownership passes to the next tile.
struct CutLine {
  double along_start_m = 0;     // coordinate along the boundary of the first cell's start
  double cell_m = 0;
  std::vector<double> cut_m;    // per cell along: where the next tile begins (across coordinate)
  double CutAt(double along_m) const;
};

class TileOwnership {
 public:
  TileOwnership() = default;
  explicit TileOwnership(const TileGrid& grid);  // straight core boundaries

  // (col, row) of the tile that keeps what lies at a ground point: the core
  // owner, moved across a boundary where that boundary's cut line says so.
  // The tile returned always has the point inside its extent (lines stay in
  // the overlap band).
  Eigen::Vector2i Owner(double east_m, double north_m) const;
  const TileGrid& grid() const { return grid_; }
  // Lines with a cut, for reports: how far they stray from the straight boundary.
  std::size_t lines() const;
  double MeanDeviationM() const;  // mean |cut - boundary| over all cells of all lines [m]

 private:
  friend TileOwnership PlanSeamLines(const SeamLineOptions& options, const std::vector<TileSpec>& tiles,
                                     const std::vector<SurfaceHeight>& surfaces);
  TileGrid grid_;
  // Between (col, row) and (col + 1, row): index row * (cols - 1) + col; empty line = straight.
  std::vector<CutLine> vertical_;
  // Between (col, row) and (col, row + 1): index col * (rows - 1) + row.
  std::vector<CutLine> horizontal_;
};

// Cut lines for every boundary between two tiles both present in `tiles`,
// from their surfaces (same order); a boundary with a tile missing stays
// straight. All tiles must share one grid.
TileOwnership PlanSeamLines(const SeamLineOptions& options, const std::vector<TileSpec>& tiles,
                            const std::vector<SurfaceHeight>& surfaces);

// The same with each tile's surface taken from its clouds' opaque (>= 0.5)
// Gaussian centres, the highest per cell: for clouds as dense as the
// line's cells (tests, dense heights). A trained scene has about one
// Gaussian per square metre, most of them translucent: render its DSM
// instead (pipeline/merge_tiles.cpp). Nothing is computed when the lines
// are disabled.
TileOwnership PlanSeamLinesOnCentres(const SeamLineOptions& options, const TileSource& tiles);
TileOwnership PlanSeamLinesOnCentres(const SeamLineOptions& options, const std::vector<TileCloud>& tiles);

}  // namespace skyfall
