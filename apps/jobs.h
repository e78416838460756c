// Stage jobs shared by the single-stage commands and the batch driver: each
// reads its inputs from files, runs the library stage and writes its outputs
// atomically, so `skyfall splat train` and `skyfall run-tile` behave alike.
#pragma once

#include <string>

#include "core/aoi.h"
#include "core/stage.h"
#include "sfm/sfm.h"
#include "splat/trainer.h"

namespace skyfall::cli {

// SfM on a catalog; writes cameras.json, points.ply, sfm_report.json (last)
// and the COLMAP model under out_dir.
SfmResult RunSfmJob(const SfmOptions& options, const AoiCatalog& catalog, const std::string& out_dir,
                    bool colmap_images, Progress& progress);

struct TrainJob {
  std::string sfm_dir;                  // written by RunSfmJob / `skyfall sfm`
  std::string out_dir;                  // scene.ply, train_report.json, checkpoints/
  TrainOptions options;
  int downscale = 1;                    // image downscale factor
  std::string depth_prior = "surface";  // "surface", "none" or "cmd:COMMAND"
  // Appearance model: "on", "off", or "auto" (on when the training views
  // were taken on more than one date).
  std::string appearance = "auto";
  double init_max_scale_m = 0;  // cap on the initial Gaussian size (0 = none)
};

// Trains (resuming from out_dir/checkpoints when possible), then writes
// scene.ply and train_report.json.
TrainResult RunTrainJob(TrainJob job, Progress& progress);

}  // namespace skyfall::cli
