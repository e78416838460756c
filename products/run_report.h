// Error against run time: joins a training run's series (train_report.json)
// with DSM evaluations of its snapshots, and plots both against elapsed
// seconds.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "core/aoi.h"
#include "products/dsm.h"

namespace skyfall {

struct RunPoint {
  int iteration = 0;
  double elapsed_s = 0;
  double loss = 0;          // NaN when unknown
  double psnr_test_db = 0;  // NaN when unknown
  double gaussians = 0;
  double dsm_mae_m = 0;     // NaN when the iteration has no snapshot
  double dsm_rmse_m = 0;
};

// Reads DIR/train_report.json and, when `catalog` has a truth grid, exports
// and compares every DIR/checkpoints/snapshots/scene_<iteration>.ply.
std::vector<RunPoint> EvaluateRun(const std::string& run_dir, const AoiCatalog& catalog,
                                  const DsmCompareOptions& options);

// Writes error_vs_time.csv and error_vs_time.png (MAE and PSNR against
// elapsed seconds) into `out_dir`.
void WriteRunReport(const std::vector<RunPoint>& points, const std::string& out_dir);

// One scene of a multi-scene benchmark: its DSM error and the run's time.
struct ScenePoint {
  std::string scene;
  double seconds = 0;     // whole run
  double mae_m = 0;       // trained scene's DSM
  double dense_mae_m = 0; // dense heights alone (NaN when unknown)
  bool tuned_on = false;  // a setting was chosen on this scene
};

// An axis-aligned box in an image [px]: top-left corner, y down.
struct PixelBox {
  int x = 0, y = 0, width = 0, height = 0;
  bool Overlaps(const PixelBox& o) const {
    return x < o.x + o.width && o.x < x + width && y < o.y + o.height && o.y < y + height;
  }
  bool Inside(const PixelBox& o) const {
    return x >= o.x && y >= o.y && x + width <= o.x + o.width && y + height <= o.y + o.height;
  }
};

// Boxes for labels of `sizes` (width, height) beside their `anchors` (the
// points they name, centre (x, y)), so that labels of scenes with nearly
// the same error and time stay readable: each label takes the first spot,
// right of its point and then left of it, level with it and then one label
// height at a time above and below, that overlaps no earlier label and no
// `obstacles` (the markers) and lies inside `bounds`; when none is free,
// the spot right of and level with its point. `gap_px` separates a label
// from its point.
std::vector<PixelBox> PlaceLabels(const std::vector<std::array<int, 2>>& anchors,
                                  const std::vector<std::array<int, 2>>& sizes, const std::vector<PixelBox>& obstacles,
                                  const PixelBox& bounds, int gap_px);

// A chart axis with round tick marks: [lo, hi] widened to whole steps of
// 1, 2, 2.5 or 5 times a power of ten, the smallest such step that needs at
// most `max_ticks` ticks (ends included; 3 at least) for the range given.
struct NiceAxis {
  double lo = 0, hi = 1, step = 1;
  int Decimals() const;  // digits after the point that tell the ticks apart
};
NiceAxis NiceAxisOf(double lo, double hi, int max_ticks);

// A scatter of DSM MAE against run time, one labelled point per scene
// (trained: filled; dense alone: open; tuned-on scenes in grey), as a PNG.
void WriteScenesPlot(const std::vector<ScenePoint>& scenes, const std::string& png_path);

}  // namespace skyfall
