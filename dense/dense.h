// Dense heights for satellite views: a plane sweep in ground space. Each
// image is warped onto a horizontal grid at every candidate height; image
// pairs score each height with windowed normalized cross-correlation (so a
// change of gain and offset between dates costs nothing); the pair costs are
// averaged after truncation (an occluded pair adds the same constant at every
// height, so it does not bias the choice) and semi-global matching
// regularizes the cost volume before the best height per cell is taken.
// This is what s2p does per pair in rectified image space; in ground space
// the pairs share one volume and the result is directly a height field.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/ground_cell.h"
#include "core/option_range.h"
#include "core/pinhole.h"
#include "core/stage.h"
#include "core/tile.h"
#include "dense/hole_fill.h"

namespace skyfall {

// The pairs the sweep correlates.
struct DensePairOptions {
  int max = 200;               // pairs kept, most verified tie points first
  int min_matches = 50;        // verified tie points for a pair to be considered
  double min_angle_deg = 4.0;  // below, heights are too weakly constrained
  double max_angle_deg = 40.0; // above, the views differ too much to correlate
};

// Semi-global smoothing of the cost volume [cost units].
struct DenseSgmOptions {
  double p1 = 0.06;  // penalty for a one-step height change between cells
  double p2 = 2.0;   // penalty for a larger change (walls)
};

// A coarse sweep up to `above_m` above the tie points' range looks for
// surfaces that hold no tie point (a tower at a coarse GSD) and raises the
// sweep's range to them (RaiseRangeToProbe). 0 = off.
struct DenseRangeProbeOptions {
  double above_m = 200.0;
  // The probe runs only for imagery whose finest GSD is at least this: at
  // sub-metre GSD the tie points reach the tall roofs, and with few pairs
  // the probe's chance matches only raised the range (decision D-122).
  double min_gsd_m = 1.0;
};

// Before filling, holes get a second chance at a coarser scale: a sweep on
// a grid of `factor` x cell_m, with windows as many cells wide, on images
// blurred to that cell. A weakly textured surface (a tiled roof whose
// courses alias, a plain slab) that no 5-cell window correlates often does
// over a window this much wider. Ground no pair sees (OccludedAtGround) is
// not taken from it. 1 = off.
struct DenseCoarseOptions {
  int factor = 3;
  int window_cells = 5;  // the coarse sweep's NCC window side [coarse cells], odd
};

// Windows fatten what they straddle: beside a roof's edge the roof's
// texture fills most of a ground cell's window, and a band of ground about
// a window radius wide takes the roof's height. Filled cells are decided
// again (DenseStepOptions) with adaptive support weights (Yoon and
// Kweon's): a window of `radius_cells` whose cells weigh, for each pair of
// views, by how like the centre they look in both views (the mean of the
// two grey differences over `grey_sigma`, on grey scaled so its 99th
// percentile is 1) and by distance, so the centre's own surface decides,
// not the wall's other side. Weights from the most nadir view alone left a
// stereo pair's filled ground leaning toward its walls (decision D-159).
// Deciding measured cells beside steps the same way was tried and not
// adopted (decision D-063).
struct DenseSupportOptions {
  int radius_cells = 4;     // [cells] the weighted window's radius (9 x 9 cells)
  double grey_sigma = 0.05; // mean grey difference of the pair's two views at which a cell's weight falls to 1/e
};

// After filling, each filled cell (not from the coarse sweep) is scored at
// the ground (the terrain model) and at a roof (its fill where raised, else
// the lowest raised measured height in reach) with the adaptive support
// weights, and takes the other side where that matches clearly better
// (min_m, cost_margin, max_cost); a cell filled at the ground with measured
// ground within reach_cells keeps it (beside a step the roof wins by
// fattening). The fill rules decide from geometry alone: holes in roofs
// that join the unmatched streets beside them took the terrain (decision
// D-096). (Pulling steps onto matched ground back by a cell after filling
// was tried and not adopted: decisions D-082 and D-083.)
struct DenseStepOptions {
  double min_m = 2.0;       // [m] a rise beyond this within reach_cells is a step
  int reach_cells = 3;      // [cells] measured ground this near keeps a filled cell at the ground
  double cost_margin = 0.1; // a cell changes side only for a cost this much lower (and <= max_cost)
  // A cell filled at the ground where no view sees the ground (beside a
  // wall every view looks away from, as both views of a pair often do)
  // takes its roof when the roof's cost is at most this; 0 = never.
  // Stricter than max_cost: the hidden ground beside a wall is also where a
  // roof's windows reach over the edge (decision D-154).
  double unseen_ground_roof_cost = 0.3;
  bool decide_filled_sides = true;
};

// A second sweep that scores each height of a cell only with the pairs
// whose two views see that point, judged against the first sweep's surface
// (holes filled): beside a wall half the views see the ground and the other
// half the wall, and averaging them all favours the roof.
struct DenseVisibilityOptions {
  bool pass = true;
  // Surface cells this near a cell (along the ray) do not hide it; -1 = the
  // NCC window's radius. Beside a step they are the band that the windows
  // fatten (ground at the roof's height), and counted as occluders they hid
  // the ground under them from every view, so that the roof won there for
  // want of a rival. 0 = every cell hides.
  int near_cells = -1;
  // A point counts as seen when the first surface rises at most this much
  // above the ray toward the camera [m]: the first surface's own error.
  double tolerance_m = 1.0;
  // Only the measured surface and the occluded ground (filled with the
  // terrain) hide what is behind them, not the holes the views see: a
  // street between two roofs that the first sweep missed is filled at the
  // roofs' height, and with that fill hiding it no view would see the
  // street's own heights in the second sweep (D-062). Heights seen by few
  // pairs get a noisy mean whose chance minima would win: the mean is taken
  // as if this many more pairs had added the truncation cost. Deciding the
  // sides of filled cells, at most as many as there are other pairs
  // (decision D-142).
  double prior_pairs = 2.0;
};

// The dense stage's options, in named parts; the run configuration keeps
// flat keys (dense.sgm_p2, dense.visibility_pass, ...), given in Visit().
struct DenseOptions {
  // Ground sampling of the height grid [m]; 0 (the default): follows the
  // imagery, AutomaticCellM.
  double cell_m = 0.0;
  double height_step_m = 0.25;      // sweep step [m]; about a third of a pixel of parallax for WV3 pairs
  double height_margin_m = 4.0;     // added beyond the tie points' height percentiles [m]
  double height_percentile = 0.005; // tie-point heights outside [p, 1-p] are ignored for the range
  int max_heights = 600;            // longer ranges are swept in coarser steps (memory: cells x heights x 4 bytes)
  DenseRangeProbeOptions range_probe;
  DensePairOptions pairs;
  int window_cells = 5;             // NCC window side [cells], odd
  double cost_truncation = 0.8;     // per-pair cost (1 - NCC) is capped here
  double min_std = 0.004;           // window standard deviation (of the normalized image) below which NCC is undefined
  // Sensor noise adds its variance to every window's variance but nothing to
  // the covariance between two views, so a true match's NCC falls as the
  // noise grows against the texture: 3 DN left 80% of a stereo pair's
  // street cells unmatched (decision D-161). This fraction of each view's
  // estimated noise variance (EstimateNoiseStd) is taken from its windows'
  // variances before NCC. Bilinear warping carries 4/9 of the variance on
  // average; 0.3 was chosen on the tuning pair. 0 = plain NCC.
  double noise_compensation = 0.3;
  DenseSgmOptions sgm;
  double max_cost = 0.55;           // cells whose matching cost at the chosen height exceeds this get no height
  double max_median_deviation_m = 2.0;  // cells further than this from their 3x3 median get no height (speckle)
  // Holes (cells without a height) are filled (FillHoles): ground no pair
  // can see (OccludedAtGround) takes the terrain; any other hole looks for
  // the lowest height above the ground within fill.radius_m (doubled until
  // something is in reach): ground takes the terrain, a raised height is
  // added to the opening at the hole. Filled cells are flagged.
  bool fill_holes = true;
  // Whether ground whose ray toward a view leaves the grid counts as hidden
  // from that view (as if the grid's highest surface stood just outside):
  // the city goes on beyond the grid, and a street near the edge seen only
  // through the edge was taken for seen ground and filled from the roofs
  // beside it (decision D-093).
  bool fill_edge_hides = true;
  // Before filling, small patches of matched cells (under
  // floating_patch_max_m2) standing wholly more than floating_patch_min_rise_m
  // above the terrain model are made holes (RemoveFloatingPatches): matches
  // in the air above hidden streets, on what two views see behind the point.
  // 0 = off.
  double floating_patch_max_m2 = 25.0;
  double floating_patch_min_rise_m = 20.0;
  DenseCoarseOptions coarse;
  DenseSupportOptions support;
  DenseStepOptions steps;
  // How holes are filled (FillHoles): run configuration keys dense.fill_*.
  HoleFillOptions fill;
  DenseVisibilityOptions visibility;
  void Check() const;               // throws Error("dense", field, ...)
};
template <class IO> void Visit(IO& io, DenseOptions& o) {
  io("cell_m", o.cell_m,
     "Height grid cell; 0 = automatic from the imagery (0.5 m for sub-metre sensors, else the multiple of 0.5 m "
     "nearest the finest view's GSD)", range::Or(range::Above(0), 0, "automatic"));
  io("height_step_m", o.height_step_m,
     "Step between the candidate heights of the plane sweep", range::Above(0));
  io("height_margin_m", o.height_margin_m,
     "Added beyond the tie points' height percentiles to form the sweep's height range", range::AtLeast(0));
  io("height_percentile", o.height_percentile,
     "Tie-point heights outside the [p, 1-p] percentiles are ignored for the height range", range::FromBelow(0, 0.5));
  io("max_heights", o.max_heights,
     "Most candidate heights per sweep; longer ranges are swept in coarser steps (memory: cells x heights x 4 bytes)",
     range::AtLeast(2));
  io("range_probe_above_m", o.range_probe.above_m,
     "A coarse sweep up to this far above the tie points' height range looks for surfaces without tie points (a "
     "tower in coarse imagery) and raises the sweep's range to them; 0 = off", range::In(0, 5000));
  io("range_probe_min_gsd_m", o.range_probe.min_gsd_m,
     "The range probe runs only for imagery whose finest GSD is at least this (sub-metre imagery has tie points on "
     "its tall roofs)", range::AtLeast(0));
  io("window_cells", o.window_cells,
     "Side of the NCC window, odd", range::Odd(range::AtLeast(3)));
  io("max_pairs", o.pairs.max,
     "Image pairs used, most verified tie points first", range::AtLeast(1));
  io("min_pair_matches", o.pairs.min_matches,
     "Verified tie points an image pair needs to be considered", range::AtLeast(0));
  io("min_pair_angle_deg", o.pairs.min_angle_deg,
     "Pairs with a smaller intersection angle are not used (heights too weakly constrained)", range::AtLeast(0));
  io("max_pair_angle_deg", o.pairs.max_angle_deg,
     "Pairs with a larger intersection angle are not used (views too different to correlate)",
     range::AboveUpTo(0, 180));
  io("cost_truncation", o.cost_truncation,
     "Each pair's matching cost (1 - NCC) is capped at this value", range::Above(0));
  io("min_std", o.min_std,
     "Window standard deviation (of the normalized image) below which NCC is undefined and the pair adds the capped "
     "cost", range::Above(0));
  io("noise_compensation", o.noise_compensation,
     "Fraction of each view's estimated sensor-noise variance taken from its windows' variances before NCC, so that "
     "noise does not lower a true match's correlation; 0 = plain NCC", range::In(0, 1));
  io("sgm_p1", o.sgm.p1,
     "SGM penalty for a one-step height change between neighbouring cells, in cost units", range::AtLeast(0));
  io("sgm_p2", o.sgm.p2,
     "SGM penalty for a larger height change (walls), in cost units", range::AtLeast(0));
  io("max_cost", o.max_cost,
     "Cells whose matching cost at the chosen height exceeds this get no height", range::Above(0));
  io("max_median_deviation_m", o.max_median_deviation_m,
     "Cells further than this from their 3x3 median get no height (speckle)", range::Above(0));
  io("fill_holes", o.fill_holes,
     "Fill cells without a height from their surroundings and the terrain model (filled cells are flagged)");
  io("coarse_factor", o.coarse.factor,
     "Before filling, holes get a second sweep on a grid this many times coarser, on images blurred to it; 1 = off",
     range::AtLeast(1));
  io("coarse_window_cells", o.coarse.window_cells,
     "NCC window side of the coarse sweep, in coarse cells, odd", range::Odd(range::AtLeast(3)));
  io("step_min_m", o.steps.min_m,
     "decide_filled_sides: a filled cell's roof side must stand more than this above its ground side", range::Above(0));
  io("step_reach_cells", o.steps.reach_cells,
     "decide_filled_sides: a cell filled at the ground with measured ground this near keeps the ground",
     range::AtLeast(1));
  io("support_radius_cells", o.support.radius_cells,
     "Radius of the adaptive support-weight window", range::AtLeast(1));
  io("support_grey_sigma", o.support.grey_sigma,
     "Grey difference from the window's centre, the mean of a pair's two views, at which a cell's support weight "
     "falls to 1/e (on grey scaled so that its 99th percentile is 1)", range::Above(0));
  io("step_cost_margin", o.steps.cost_margin,
     "A cell changes side only when the other side's cost is lower by this much (and at most max_cost)",
     range::AtLeast(0));
  io("unseen_ground_roof_cost", o.steps.unseen_ground_roof_cost,
     "decide_filled_sides: a cell filled at the ground where no view can see the ground takes the roof when the "
     "roof's cost is at most this (0 = never)",
     range::AtLeast(0));
  io("decide_filled_sides", o.steps.decide_filled_sides,
     "After filling, score each filled cell at the ground and at a roof, and let it take the other side where that "
     "matches clearly better");
  Visit(io, o.fill);  // the hole filling's options, under dense.fill_*
  io("fill_edge_hides", o.fill_edge_hides,
     "Ground whose ray toward a view leaves the grid counts as hidden from that view (the city goes on beyond the "
     "grid)");
  io("floating_patch_max_m2", o.floating_patch_max_m2,
     "Before filling, patches of matched cells smaller than this that stand wholly more than "
     "floating_patch_min_rise_m above the terrain model become holes; 0 = off", range::AtLeast(0));
  io("floating_patch_min_rise_m", o.floating_patch_min_rise_m,
     "Height above the terrain model beyond which a small patch counts as floating (see floating_patch_max_m2)",
     range::AtLeast(0));
  io("visibility_pass", o.visibility.pass,
     "Run a second sweep that scores each height only with the pairs whose two views see that point");
  io("visibility_tolerance_m", o.visibility.tolerance_m,
     "A point counts as seen when the first surface rises at most this much above its ray toward the camera",
     range::AtLeast(0));
  io("visibility_near_cells", o.visibility.near_cells,
     "Surface cells this near a cell along the ray do not hide it; -1 = the NCC window's radius, 0 = every cell "
     "hides", range::Or(range::AtLeast(0), -1, "the NCC window's radius"));
  io("visibility_prior_pairs", o.visibility.prior_pairs,
     "In the visibility pass, each height's mean cost is taken as if this many more pairs had added the capped cost "
     "(deciding filled cells' sides, at most the number of other pairs)",
     range::AtLeast(0));
}

// One view: its camera in the frame of the grid (ENU) and its pixels.
struct DenseView {
  std::string name;
  PinholeCamera camera;
  int width_px = 0, height_px = 0;
  int bands = 0;
  std::vector<float> pixels;  // `bands` values per pixel, row-major, any radiometric range
};

// A candidate pair (indices into the views) with its verified tie points.
struct DensePair {
  int a = 0, b = 0;
  int verified = 0;
};

// A height field on a regular ENU grid: cell (i, j) is centred at
// (x0_m + i * cell_m, y0_m + j * cell_m); i grows east, j north.
struct HeightGrid {
  double x0_m = 0, y0_m = 0, cell_m = 0;
  int nx = 0, ny = 0;
  std::vector<float> height_m;                  // ENU up [m]; NaN where there is no answer
  std::vector<float> cost;                      // matching cost at that height [0, cost_truncation]
  std::vector<std::uint8_t> filled;             // 1 where the height was filled in, not measured
  std::vector<FillRule> fill_rule;              // how each cell got its height (kMatched where measured)
  std::vector<float> terrain_m;                 // ENU up of the bare-earth model (TerrainModel); NaN without ground
  std::vector<std::uint8_t> views;              // views of the matched pairs that see the cell's surface
  std::vector<std::array<std::uint8_t, 3>> rgb; // colour of the surface (0 where no height)
  std::size_t Index(int i, int j) const { return static_cast<std::size_t>(j) * nx + i; }
};

struct DenseResult {
  HeightGrid grid;
  std::vector<DensePair> pairs_used;
  StageReport report;
};

// The automatic cell (core/ground_cell.h: DenseCellForGsdM) for the finest
// view's GSD at `centre_enu_m` (depth / focal length).
double AutomaticCellM(const std::vector<DenseView>& views, const Eigen::Vector3d& centre_enu_m);

// The grid covers the tie points' horizontal extent, clipped to
// `extent_enu_m` when given (a tile's core plus overlap: the views' margins
// beyond it are another tile's work); the heights of the tie points inside
// set the sweep range (raised by the range probe). Status "degenerate" when
// fewer than 3 tie points lie inside or no pair qualifies.
DenseResult RunDenseHeights(const DenseOptions& options, const std::vector<DenseView>& views,
                            const std::vector<DensePair>& pairs, const std::vector<Eigen::Vector3d>& tie_points_enu_m,
                            Progress& progress, const std::optional<GroundBox>& extent_enu_m = std::nullopt);

// The pairs the sweep would use: qualifying pairs by decreasing verified count.
std::vector<DensePair> SelectDensePairs(const DenseOptions& options, const std::vector<DenseView>& views,
                                        const std::vector<DensePair>& pairs, const Eigen::Vector3d& scene_centre_enu_m);

// Per cell of `grid`, the height above which a point on the cell's vertical
// is seen from a camera in direction `to_camera` (ENU, from the scene; an
// orthographic approximation, fine for satellites): the highest point of
// `surface_m` (nx x ny, NaN = unknown, ignored) along the ray, less the
// ray's rise to it. -infinity where nothing hides the cell; the march stops
// once the ray is below `floor_m` (heights below it are never asked). The
// first `near_cells` cells along the ray hide nothing. With
// `edge_hides`, a ray that leaves the grid is taken to pass the grid's
// highest surface just outside: what stands beyond the grid is unknown.
std::vector<float> VisibleAbove(const HeightGrid& grid, const std::vector<float>& surface_m,
                                const Eigen::Vector3d& to_camera, double floor_m, int near_cells = 0,
                                bool edge_hides = false);

// Cells of `surface_m` (nx x ny, NaN = hole) whose ground point (the
// terrain's height plus `tolerance_m`) no image pair sees past the measured
// surface with both its views (`to_cameras`: ENU directions toward the
// views; `pairs`: the pairs the sweep matches with, as indices into
// `to_cameras`): holes that no pair can measure, whatever the texture. Two
// views that each see a street between tall buildings but are too far apart
// to be matched (or were not selected) do not make it measurable. 0 for
// measured cells. With `edge_hides`, a view whose ray leaves the grid
// below its highest surface does not see the point (VisibleAbove). Throws
// Error for a pair index out of range.
std::vector<std::uint8_t> OccludedAtGround(const HeightGrid& grid, const std::vector<float>& surface_m,
                                           const std::vector<float>& terrain_m,
                                           const std::vector<Eigen::Vector3d>& to_cameras,
                                           const std::vector<std::array<int, 2>>& pairs, double tolerance_m,
                                           double floor_m, bool edge_hides);

// Semi-global matching over a cost volume laid out cell-major
// (cost[(j * nx + i) * heights + d]); returns the aggregated volume (sum over
// 8 directions). Exposed for its tests.
std::vector<float> AggregateSgm(const std::vector<float>& cost, int nx, int ny, int heights, float p1, float p2);

}  // namespace skyfall
