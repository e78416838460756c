// Measuring novel views against truth: orbit cameras that no training
// episode used, and masked PSNR / SSIM of renders against truth images,
// with a gallery to look at (scripts/bench_idu.sh).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/stage.h"

namespace skyfall {

struct EvalOrbitOptions {
  std::vector<double> elevations_deg = {75.0, 60.0, 45.0};
  int views_per_elevation = 4;
  // Radius as a multiple of the looked-at box's side (the middle of the
  // synthesis stage's 0.59 -> 0.49).
  double radius_per_core = 0.54;
  double min_radius_m = 150.0;  // as the synthesis stage's floor
  double fov_deg = 60.0;
  int width_px = 256, height_px = 256;
};

// Orbit cameras around the points halfway between the synthesis stage's 3 x 3
// look-at points (at 1/3 and 2/3 of the tile's reconstructed core), at
// azimuths offset from the training rings, at the surface height of the
// tile's dense heights. Writes a cameras.json (skyfall.cameras/1) and
// returns the number of cameras.
int WriteEvalOrbitCameras(const std::string& tile_dir, const EvalOrbitOptions& options, const std::string& out_json);

// Masked comparison of renders (<dir>/<name>_rgb.png, as `splat render`
// writes them) with truth (<truth>/<name>.png and <name>_mask.png, as
// `synth --render-cameras` writes them), for each camera of `cameras_json`.
struct ViewScores {
  std::string name;
  double elevation_deg = 0;
  std::vector<double> psnr_db, ssim;  // one per render folder
};
struct ViewComparison {
  std::vector<ViewScores> views;
  // Per elevation (rounded to 0.1 deg) and render folder: means over views.
  std::map<double, std::vector<double>> psnr_db, ssim;
};
// Writes out_dir/compare.json and out_dir/gallery.png (one row per
// elevation: each render folder's view, then the truth).
ViewComparison CompareViews(const std::string& cameras_json, const std::string& truth_dir,
                            const std::vector<std::string>& render_dirs, const std::string& out_dir, Progress& progress);

// Mean SSIM (Gaussian window, sigma 1.5 px, the usual constants for [0, 1]
// images) over the pixels where `mask` is non-zero; RGB, 3 floats per pixel.
// NaN when the mask is empty. (PSNR over a mask: MaskedPsnr, splat/losses.h.)
double MaskedSsim(const std::vector<float>& a, const std::vector<float>& b, const std::vector<std::uint8_t>& mask,
                  int width_px, int height_px);

}  // namespace skyfall
