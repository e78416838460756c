// Error against run time: joins a training run's series (train_report.json)
// with DSM evaluations of its snapshots, and plots both against elapsed
// seconds.
#pragma once

#include <string>
#include <vector>

#include "core/aoi.h"
#include "merge/dsm.h"

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

// A scatter of DSM MAE against run time, one labelled point per scene
// (trained: filled; dense alone: open; tuned-on scenes in grey), as a PNG.
void WriteScenesPlot(const std::vector<ScenePoint>& scenes, const std::string& png_path);

}  // namespace skyfall
