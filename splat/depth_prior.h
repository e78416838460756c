// Depth priors for pseudo-camera supervision (Skyfall-GS uses the monocular
// estimator MoGe, whose weights cannot be had here). A prior maps a rendered
// pseudo view to a depth map; only its correlation with the rendered depth
// is used (1 - |Pearson r|), so any affine depth or disparity works.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "core/option_range.h"
#include "core/pinhole.h"

namespace skyfall {

struct DepthMap {
  std::vector<float> depth;           // per pixel, any affine scale
  std::vector<unsigned char> valid;   // 0 where the prior has no answer
  // Per pixel confidence of the depth in [0, 1] (SurfaceDepthPrior with
  // point weights); empty: full confidence wherever valid.
  std::vector<float> weight;
};

class DepthPrior {
 public:
  virtual ~DepthPrior() = default;
  // `rgb`: the rendered view, 3 floats per pixel in [0, 1].
  virtual DepthMap Estimate(const PinholeCamera& camera, const std::vector<float>& rgb) = 0;
};

// Built-in, weight-free prior: the depth of a height field fitted to the SfM
// tie points (median height per cell, holes filled from their neighbours),
// ray-cast from the pseudo camera. It knows the coarse surface, not detail.
class SurfaceDepthPrior final : public DepthPrior {
 public:
  // `point_weights` (optional, one per point in [0, 1]): the confidence of
  // each point's height; a cell takes the lowest of its points', a cell no
  // point falls in 0. Ray casts then return each pixel's weight.
  SurfaceDepthPrior(const std::vector<Eigen::Vector3f>& points, double cell_m,
                    const std::vector<float>& point_weights = {});
  DepthMap Estimate(const PinholeCamera& camera, const std::vector<float>& rgb) override;
  // The same depth less `reference_depth_m`, subtracted in double: satellite
  // depths (~6e5 m) keep only ~6 cm in float, their differences keep all.
  DepthMap DepthRelativeTo(const PinholeCamera& camera, double reference_depth_m) const;
  // The same for a camera looking straight down from far away (NadirCamera):
  // each ray meets the surface within a few fixed-point steps, so this costs
  // a few height lookups per pixel instead of a march.
  DepthMap NadirDepthRelativeTo(const PinholeCamera& camera, double reference_depth_m) const;
  // Height of the fitted surface [m in the points' frame]; NaN outside.
  double HeightAt(double x_m, double y_m) const;
  // Confidence of that height (1 without point weights; 0 outside).
  float WeightAt(double x_m, double y_m) const;

 private:
  // Camera depth at which the ray c + t d (unit camera z) first meets the
  // surface, NaN if it does not within the grid.
  double FirstHit(const Eigen::Vector3d& c, const Eigen::Vector3d& d) const;
  // The highest cell of each block of kBlockCells x kBlockCells cells.
  void BuildBlockMaxima();
  // Row-major index of the cell holding (x, y), -1 outside the grid.
  std::ptrdiff_t CellIndex(double x_m, double y_m) const;

  double x0_ = 0, y0_ = 0, cell_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<float> height_;
  std::vector<float> weight_;  // per cell; empty without point weights
  float min_z_ = 0, max_z_ = 0;
  static constexpr int kBlockCells = 8;
  int bx_ = 0, by_ = 0;          // blocks per row and column
  std::vector<float> block_max_;  // per block, row-major
};

// External estimator: runs `command` with {in} replaced by a PNG of the view
// and {out} by the path of a float32 GeoTIFF/TIFF depth map it must write
// (same size; non-finite = invalid). E.g. a user's MoGe wrapper script.
class CommandDepthPrior final : public DepthPrior {
 public:
  CommandDepthPrior(std::string command, std::string work_dir);
  DepthMap Estimate(const PinholeCamera& camera, const std::vector<float>& rgb) override;

 private:
  std::string command_;
  std::string work_dir_;
  int calls_ = 0;
};

// Pseudo cameras for depth supervision: looking at points near the scene
// centre from `radius_m`, at elevations in [min, max] degrees and random
// azimuths, with a 60 degree field of view (paper: 80 -> 45 deg, radii 300 -> 250).
struct PseudoCameraOptions {
  double radius_m = 250.0;
  double look_at_sigma_m = 64.0;
  double min_elevation_deg = 45.0;
  double max_elevation_deg = 80.0;
  int size_px = 192;
  double fov_deg = 60.0;
};
template <class IO> void Visit(IO& io, PseudoCameraOptions& o) {
  io("radius_m", o.radius_m,
     "Distance of a pseudo camera from its look-at point", range::Above(0));
  io("look_at_sigma_m", o.look_at_sigma_m,
     "Standard deviation of the look-at points' horizontal offset from the scene centre (also for the surface "
     "anchor's nadir patches)", range::AtLeast(0));
  io("min_elevation_deg", o.min_elevation_deg,
     "Lowest elevation of a pseudo camera (azimuths are random)", range::In(0, 90));
  io("max_elevation_deg", o.max_elevation_deg,
     "Highest elevation of a pseudo camera", range::In(0, 90));
  io("size_px", o.size_px,
     "Side of a pseudo view (square)", range::AtLeast(16));
  io("fov_deg", o.fov_deg,
     "Field of view of a pseudo camera", range::Inside(0, 170));
}
// A camera `height_m` above `look_at` (ENU: z up) looking straight down, x
// to the east and image rows to the south, with `gsd_m` ground pixels at the
// look-at height and size_px x size_px pixels: the view the DSM is exported
// from, over a patch of the scene.
PinholeCamera NadirCamera(const Eigen::Vector3d& look_at, double gsd_m, int size_px, double height_m);

PinholeCamera SamplePseudoCamera(const PseudoCameraOptions& options, const Eigen::Vector3d& scene_centre,
                                 std::uint64_t sample);

}  // namespace skyfall
