// The plane sweep's parts that the dense stage's sources share (not a
// public header): grey images, the sweep of one run, its cost volume and
// the heights picked from it, the coarse sweep, what each view sees, and
// the decision of filled cells' sides.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "core/stage.h"
#include "dense/dense.h"

namespace skyfall::dense_detail {

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();

// Grey level of a view scaled so that its 99th percentile is 1: NCC ignores
// the scale, but min_std is then the same threshold for every sensor range.
struct GreyImage {
  int width = 0, height = 0;
  std::vector<float> values;
  // The sensor noise's standard deviation in the same units: ToGrey's
  // estimate (EstimateNoiseStd), which the dense stage scales to what its
  // cells sample where they are finer than the pixels (dense.cpp, SlotViews).
  float noise_std = 0;
};

GreyImage ToGrey(const DenseView& v);

// The standard deviation of white sensor noise in `g`, from the flattest
// tenth of the image: Immerkaer's Laplacian mask (its response to noise
// has 6 times the noise's deviation and to a linear ramp none), its rms
// per block of 16 x 16 pixels, and the 10th percentile of the blocks.
// Texture raises the estimate; blocks holding a NaN are skipped; 0 for an
// image with no whole block.
float EstimateNoiseStd(const GreyImage& g);

using Projection = Eigen::Matrix<double, 3, 4>;
Projection ProjectionOf(const PinholeCamera& c);

// What the sweeps of one run share: the grid, the heights and the views.
struct Sweep {
  const DenseOptions& o;
  const HeightGrid& grid;  // geometry only
  double z_lo = 0;
  double step_m = 0;  // height_step_m, or coarser where the range needs more than max_heights
  int nh = 0;
  const std::vector<DensePair>& pairs;
  const std::vector<int>& slot;  // view index -> index into grey / projection
  const std::vector<GreyImage>& grey;
  const std::vector<Projection>& projection;
  std::size_t Cells() const { return static_cast<std::size_t>(grid.nx) * grid.ny; }
  double Height(int d) const { return z_lo + d * step_m; }
};

// The cost volume of `s` (sweep.cpp: CostVolume).
std::vector<float> CostVolume(const Sweep& s, const std::vector<std::vector<float>>* seen_above,
                              const std::string& label, Progress& progress);

// Heights chosen from a cost volume: SGM, the best height per cell refined
// by a parabola through its neighbours, cells matching worse than max_cost
// and speckles (far from their 3x3 median) left NaN.
struct CellHeights {
  std::vector<float> height_m, cost;
  std::size_t low_cost = 0, speckles = 0;
};

CellHeights PickHeights(const Sweep& s, const std::vector<float>& cost, Progress& progress);

// The views of the sweeps at a coarser scale (the hole sweep and the range
// probe), blurred once for both: a Gaussian of half a coarse cell, `factor`
// times the fine cell, against aliasing (sweep.cpp).
struct CoarseViews {
  int factor = 0;
  std::vector<GreyImage> grey;  // per view slot
};
CoarseViews BlurForCoarseSweeps(const std::vector<GreyImage>& grey, const std::vector<Projection>& projection,
                                double fine_cell_m, int factor, const Eigen::Vector3d& centre_enu_m);

// Heights from a sweep at views.factor times the cell (sweep.cpp).
std::vector<float> CoarseSweepHeights(const Sweep& fine, const CoarseViews& views, Progress& progress);

// The highest surface that a sweep at views.factor times the cell finds
// between fine.z_lo and z_top_m (ENU up): the 4th highest of the coarse
// cells that match (max_cost) and agree with their 3 x 3 neighbours, or
// none (sweep.cpp).
std::optional<double> ProbeTopHeight(const Sweep& fine, const CoarseViews& views, double z_top_m,
                                     Progress& progress);

// Per view, the height above which each cell is seen (visibility.cpp).
std::vector<std::vector<float>> SeenAbove(const HeightGrid& g, const std::vector<float>& surface_m,
                                          const std::vector<Eigen::Vector3d>& to_cameras, double floor_m,
                                          double tolerance_m, int near_cells);

// The decision of filled cells' sides (filled_sides.cpp).
struct SidesDecided {
  std::size_t changed = 0;          // filled cells that took the other side
  std::size_t over_unseen_ground = 0;  // of them, roofs taken where no view sees the ground
};
SidesDecided DecideFilledSides(const Sweep& s, const std::vector<Eigen::Vector3d>& to_cameras,
                               const std::vector<float>& measured_m,
                               const std::vector<float>& terrain_m, const std::vector<std::uint8_t>& candidates,
                               int reach_cells, std::vector<float>& height_m, Progress& progress);

}  // namespace skyfall::dense_detail
