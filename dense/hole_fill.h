// Filling the holes of a dense height grid (cells no image pair measured)
// from what surrounds them, and the ground surface and terrain model that
// tells ground from raised surfaces. Grids are nx x ny, row-major, NaN where
// there is no height.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/option_range.h"

namespace skyfall {

// How a window meets the grid's edge: cut to the cells inside, or moved
// inside whole (as a structuring element must lie within the grid, so that
// a building in a corner is not mistaken for ground).
enum class WindowEdge { kClip, kShift };

// Minimum over the (2r+1)^2 square around each cell, ignoring NaN (NaN
// where the square holds no finite value); separable, rows then columns,
// three comparisons per cell whatever r.
std::vector<float> MinFilter(const std::vector<float>& h, int nx, int ny, int r, WindowEdge edge);

// The hole filling's rules on a grid of cells (HoleFillOptions::OnGrid):
// what FillHoles and GroundModelOf take. Nothing here is a default; a grid
// form not made by OnGrid states every field.
struct HoleFillGrid {
  int radius_cells = 0;            // first reach of a hole cell, doubled while nothing is in it
  int max_reach_cells = 0;         // cells further than this from every measured cell stay NaN
  int ground_radius_cells = 0;     // radius of the ground surface's opening (GroundSurface)
  float ground_tolerance_m = 0.0f;  // measured cells this close above the ground surface are ground
  float ground_max_rise_m = 0.0f;   // GroundSurface's max_rise_m: 0 = off
  int terrain_block_cells = 0;      // block side of the terrain model (TerrainModel)
  // A seen hole (one piece of connected hole cells) whose rim of measured
  // cells lies at least this share higher than roof_rim_min_m above the
  // ground is a roof's hole: it is filled from the raised cells in reach
  // only, not from the ground beyond the roof's edge. 0 = off.
  float roof_rim_fraction = 0.0f;
  float roof_rim_min_m = 0.0f;      // [m] above the ground, a rim cell is raised
  // Pieces of holes also take in the occluded cells: a roof's hole whose
  // ground is hidden behind the roof around it then takes the roof, not the
  // terrain. Its cells wait for the roof to come within reach.
  bool roof_rim_occluded = false;
  // A hole cell enclosed by roof (each of the 8 rays from it meets a measured
  // cell within max_reach_cells, all but one of them raised) is a roof's
  // hole whatever its piece's rim (MarkEnclosedByRoof in hole_fill.cpp).
  bool roof_enclosed = false;
  // A seen hole cell (not a roof's hole) with nothing measured within
  // radius_cells, whose lowest measured neighbour further out is raised,
  // takes the ground: a street between tall buildings that the views see
  // along its length but no pair matched is far from any measured ground,
  // and the nearest measured heights are the roofs on either side.
  bool far_raised_takes_ground = false;
  // A seen hole cell (in a roof's hole: with no roof in reach) whose lowest
  // measured height in reach is ground (within roof_rim_min_m above the
  // hole's base) takes the terrain model, which keeps a hillside's slope
  // across the hole: the base, a plain opening, is the highest of the lowest
  // heights within ground_radius_cells, and where little ground is measured
  // on a hillside that is ground far uphill. Without a terrain model at the
  // cell it keeps the base plus that lowest height. A roof less than
  // roof_rim_min_m above such a base passes for ground, and a hole in it
  // takes the terrain.
  bool seen_ground_takes_terrain = false;
};

// The hole filling's rules as the product runs them, in metres (nested in
// DenseOptions as `fill`; run configuration keys dense.fill_*). One set of
// defaults: a library user who calls FillHoles with OnGrid's result gets
// the product's algorithm.
struct HoleFillOptions {
  double radius_m = 5.0;  // first reach of a hole cell, doubled while nothing is in it
  // Cells further than this from every measured cell stay empty: beyond
  // the area the views share there is nothing to fill from, and filling it
  // would only add Gaussians to train.
  double max_reach_m = 20.0;
  // The ground surface is a morphological opening of this radius (larger
  // than half the widest building): it keeps planes and smooth terrain and
  // removes buildings and trees.
  double ground_radius_m = 30.0;
  // A measured cell at most this far above the ground surface is ground (it
  // shapes the terrain model).
  double ground_tolerance_m = 1.0;
  // Where the ground surface stands more than this above the opening of
  // twice ground_radius_m, its squares held roofs only (the ground hidden
  // between tall buildings): no ground there, and the terrain model spans
  // it from the ground measured further away. 0 = off.
  double ground_max_rise_m = 10.0;
  int terrain_block_cells = 8;  // block side of the terrain model (TerrainModel), in grid cells
  // A seen hole whose rim of measured cells is at least this share roof
  // (more than roof_rim_min_m above the ground) takes the roof, though
  // ground is within radius_m. 0 = off.
  double roof_rim_fraction = 0.9;
  double roof_rim_min_m = 2.0;  // above the ground, a rim cell is raised
  // Whether the rule also counts holes whose ground no pair sees: a hole in
  // the middle of a roof hides its own ground behind the roof around it,
  // and the occluded-ground rule alone would fill it with the terrain.
  bool roof_rim_occluded = true;
  // A hole cell enclosed by roof on all sides takes the roof even where its
  // piece of holes reaches hidden ground beyond the roof's edge.
  bool roof_enclosed = true;
  // A seen hole cell with nothing measured within radius_m, whose lowest
  // measured neighbour further out is raised, takes the ground: a street
  // between tall buildings, seen along its length but matched by no pair,
  // took the roofs' height (decision D-094).
  bool far_raised_takes_ground = true;
  // A seen hole cell whose lowest measured neighbour in reach is ground
  // takes the terrain model: on a hillside with little ground measured
  // between tall buildings, the plain opening it took before stood metres
  // above the ground downhill (decision D-102).
  bool seen_ground_takes_terrain = true;

  // The rules on a grid of `cell_m` (distances rounded to whole cells, at
  // least one).
  HoleFillGrid OnGrid(double cell_m) const;
  void Check() const;  // throws Error("dense", "fill_...", ...)
};

// As the run lists them (dense.fill_* in run_config.json).
template <class IO> void Visit(IO& io, HoleFillOptions& f) {
  io("fill_radius_m", f.radius_m,
     "A seen hole takes the lowest height above the ground within this distance (doubled while nothing is in reach)",
     range::Above(0));
  io("fill_roof_rim_fraction", f.roof_rim_fraction,
     "A seen hole whose rim of measured cells is at least this share roof takes the roof, even with ground in reach; "
     "0 = off", range::In(0, 1));
  io("fill_roof_rim_occluded", f.roof_rim_occluded,
     "The roof-rim rule also counts holes whose ground no pair sees (a hole in the middle of a roof)");
  io("fill_roof_enclosed", f.roof_enclosed,
     "A hole cell enclosed by roof on all sides takes the roof, even where its hole reaches hidden ground beyond the "
     "roof's edge");
  io("fill_far_raised_ground", f.far_raised_takes_ground,
     "A seen hole cell with nothing measured within fill_radius_m, whose lowest measured neighbour further out is "
     "raised, takes the ground");
  io("fill_seen_ground_terrain", f.seen_ground_takes_terrain,
     "A seen hole cell whose lowest measured neighbour in reach is ground takes the terrain model's height");
  io("max_fill_reach_m", f.max_reach_m,
     "Cells further than this from every measured cell stay empty", range::Above(0));
  io("fill_ground_radius_m", f.ground_radius_m,
     "Radius of the morphological opening that gives the ground surface (larger than half the widest building)",
     range::Above(0));
  io("fill_ground_max_rise_m", f.ground_max_rise_m,
     "Where the ground surface stands more than this above the opening of twice fill_ground_radius_m, it holds roofs "
     "only and the terrain model spans it; 0 = off", range::AtLeast(0));
  io("fill_ground_tolerance_m", f.ground_tolerance_m,
     "Measured cells at most this far above the ground surface are ground and shape the terrain model",
     range::AtLeast(0));
  io("fill_terrain_block_cells", f.terrain_block_cells,
     "Block side of the terrain model that spans hidden ground, in grid cells", range::AtLeast(1));
  io("fill_roof_rim_min_m", f.roof_rim_min_m,
     "A measured cell more than this above the ground is raised (a roof) for the roof-rim and enclosure rules",
     range::AtLeast(0));
}

// The ground under a height grid: its opening (GroundSurface), which tells
// ground cells from raised ones; the terrain model through the ground cells
// (TerrainModel), which also spans the holes; and what the lowest heights
// of seen holes are measured above: the plain opening, squares cut at the
// grid's edges. A slope-corrected base can fill an unmatched tall roof as
// ground on a hill; the plain opening does not (decision D-032).
struct GroundModel {
  std::vector<float> ground_m, terrain_m, seen_hole_base_m;
  int terrain_trend_terms = 0;  // the terrain's trend: 3 a plane, 6 a quadratic, 0 none
};
GroundModel GroundModelOf(const std::vector<float>& height_m, int nx, int ny, const HoleFillGrid& options);

// How a cell of the dense grid got its height: the codes of quality.tif's
// fill band (docs/outputs.md lists them).
enum class FillRule : std::uint8_t {
  kMatched = 0,         // measured by the sweep at the grid's scale
  kCoarse = 1,          // measured by the coarse sweep, at a coarser scale
  kOccludedGround = 2,  // ground no image pair sees (hidden by the surface): the terrain model
  kRoofHole = 3,        // a hole inside a roof: the roof in reach
  kSeenHole = 4,        // seen but not matched: the lowest height in reach above the ground
  kSeenGround = 5,      // seen, with ground the lowest in reach: the terrain model
  kFarRaised = 6,       // only roof beyond the first reach: the ground
  kSideByViews = 7,     // filled, then moved between ground and roof by the views (decide_filled_sides)
};

// Fills the NaN cells of `height_m` (nx x ny) within reach of a measured
// cell; returns a per-cell flag of what was filled. A cell that `occluded`
// marks (ground no image pair can see, hidden by the measured surface: the
// foot of a wall facing away from the views, a street between tall
// buildings) is ground: it takes the terrain, unless roof_rim_occluded
// counts it in a roof's hole. Any other hole (a surface
// seen but not matched: a plain roof, a shadow, a tree) takes the lowest
// height above the ground within radius_cells (doubled up to
// max_reach_cells while nothing is in reach), added to the ground at the
// hole (seen_hole_base_m): most such holes border the ground, and filling
// them from a roof would put roofs in courtyards; a hole with only roof in
// reach (inside a roof) takes the roof, and so does a hole whose rim is
// mostly roof (roof_rim_fraction), from the roof cells in reach, though
// the ground beyond the roof's edge is nearer; with far_raised_takes_ground
// a cell that found only roof beyond radius_cells (not in a roof's hole)
// takes the ground; with seen_ground_takes_terrain a cell whose lowest
// height in reach is ground takes the terrain model. Raised heights are
// measured above the ground (the base), so on a slope a raised fill stands
// on the ground near the hole, not on the downhill one.
// `rules`, when given, receives each filled cell's FillRule (kMatched elsewhere).
std::vector<std::uint8_t> FillHoles(std::vector<float>& height_m, int nx, int ny, const HoleFillGrid& options,
                                    const GroundModel& model, const std::vector<std::uint8_t>* occluded = nullptr,
                                    std::vector<FillRule>* rules = nullptr);

// The ground under `height_m` (nx x ny, NaN = unknown): a morphological
// opening with a flat square of radius `radius_cells` (the highest of the
// square minima) of the heights less their trend plane, plus that plane. It
// keeps planes exactly (up to the grid's edges) and smooth terrain, and
// removes what is narrower than the square (buildings, trees). NaN where no
// measured cell is within reach, and, when max_rise_m > 0, where it stands
// more than max_rise_m above the opening of twice the radius: there the
// squares held raised surfaces only (0 = off).
std::vector<float> GroundSurface(const std::vector<float>& height_m, int nx, int ny, int radius_cells,
                                 float max_rise_m);


// A terrain model under the whole grid, holes included: the ground cells
// (measured, within `ground_tolerance_m` of `ground_surface`) are grouped in
// blocks of terrain_block_cells; each block's plane (least squares, or the
// median of fewer than 3 cells) gives its value at the block's centre,
// blocks without ground take the trend of the known centres plus the
// harmonic interpolation of what that trend leaves of them (a hidden
// stretch of a hillside keeps the hill's slope and curvature), and
// cells interpolate the block centres bilinearly (linearly extended over the
// outer half blocks). Exact on planes; NaN everywhere when no cell is ground.
// Unlike the opening, it does not flatten across a wide hole. The trend is
// a plane, or a quadratic surface where that predicts the known blocks
// better from each other (4 x 4 spatial folds); `trend_terms`, when given,
// receives which (3 or 6; 0 with no trend).
std::vector<float> TerrainModel(const std::vector<float>& height_m, const std::vector<float>& ground_surface, int nx,
                                int ny, const HoleFillGrid& options, int* trend_terms = nullptr);

// Small patches of matched cells that float high above the terrain: where
// the ground is hidden (a street between tall buildings), the only heights
// a pair can score are in the air above it, and a few cells match there on
// what the two views see behind the point (two walls). Each piece of
// 4-connected measured cells whose neighbours differ by less than
// `smooth_step_m`, smaller than `max_cells` and all of it more than
// `min_rise_m` above `terrain_m`, is made a hole (NaN). Returns how many
// cells were removed. A tall structure is seldom so small and so alone: a
// roof matched in fragments keeps them when they lie lower than the rise.
struct FloatingPatchOptions {
  int max_cells = 0;  // 0 = off
  float min_rise_m = 20.0f;
  float smooth_step_m = 1.0f;
};
std::size_t RemoveFloatingPatches(std::vector<float>& height_m, int nx, int ny, const std::vector<float>& terrain_m,
                                  const FloatingPatchOptions& options);

}  // namespace skyfall
