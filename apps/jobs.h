// Stage jobs shared by the single-stage commands and the batch driver: each
// reads its inputs from files, runs the library stage and writes its outputs
// atomically, so `skyfall splat train` and `skyfall run-tile` behave alike.
#pragma once

#include <optional>
#include <string>

#include "core/aoi.h"
#include "core/stage.h"
#include "sfm/dense.h"
#include "sfm/sfm.h"
#include "splat/trainer.h"

namespace skyfall::cli {

// SfM on a catalog; writes cameras.json, points.ply, sfm_report.json (last)
// and the COLMAP model under out_dir.
SfmResult RunSfmJob(const SfmOptions& options, const AoiCatalog& catalog, const std::string& out_dir,
                    bool colmap_images, Progress& progress);

// Dense heights for an SfM folder (cameras.json, points.ply and the pairs of
// sfm_report.json); writes dense.ply (one point per cell with a height:
// x y z red green blue matching_cost filled) and dense_report.json (last).
// `extent_enu_m` clips the grid (a tile's extent, in the SfM frame).
DenseResult RunDenseJob(const DenseOptions& options, const std::string& sfm_dir, Progress& progress,
                        const std::optional<GroundBox>& extent_enu_m = std::nullopt);

// True when `sfm_dir` holds a finished dense stage with the same options
// over the same extent.
bool DenseDone(const std::string& sfm_dir, const DenseOptions& options, const std::optional<GroundBox>& extent_enu_m);

struct TrainJob {
  std::string sfm_dir;                  // written by RunSfmJob / `skyfall sfm`
  std::string out_dir;                  // scene.ply, train_report.json, checkpoints/
  TrainOptions options;
  int downscale = 1;                    // image downscale factor
  std::string depth_prior = "surface";  // "surface", "none" or "cmd:COMMAND"
  // Appearance model: "on", "off", or "auto" (on when the training views
  // were taken on more than one date).
  std::string appearance = "auto";
  // Cap on the initial Gaussian size [m] (0 = none). SfM points are ~3.5 m
  // apart on JAX_068, and at the paper's scaling learning rate (0.001) a
  // Gaussian shrinks at most ~e-fold per 1000 steps: uncapped, the first
  // thousands of steps render a DSM of 2-5 m blobs. Measured on JAX_068
  // (1000 steps, half resolution): DSM MAE 3.51 m uncapped, 2.69 m at 1 m,
  // 2.60 m at 0.75 m, 2.13 m at 0.4 m, but completeness 98.8 / 98.3 / 97.3 /
  // 87.9 % and held-out PSNR 17.9 / 18.2 / 17.3 / 13.6 dB.
  double init_max_scale_m = 1.0;
  // Up to this many capped Gaussians per SfM point, covering its
  // neighbourhood (see InitializeFromPoints; 1 = one per point). The cap
  // alone leaves gaps between the sparse points that training fills only
  // slowly. JAX_068, whole run with the defaults: 1 piece MAE 2.70 m,
  // completeness 98.5%, held-out PSNR 19.1 dB, 298 s; 16 pieces 2.28 m,
  // 99.2%, 21.6 dB, 495 s.
  int init_pieces = 16;
  // Where the initial Gaussians come from: "dense" (dense.ply of `skyfall
  // dense`, thinned to init_spacing_m, plus the tie points in its holes),
  // "sparse" (the tie points of points.ply) or "auto" (dense when dense.ply
  // exists). The depth prior's surface is fitted to the same points.
  std::string init_points = "auto";
  double init_spacing_m = 1.0;  // [m] one dense point per cell of this size
  // Adaptive density control (clone, split, prune): "on", "off", or "auto"
  // (on for tie-point starts, which it grows over the gaps between the
  // points; off for dense starts, which already hold one Gaussian per
  // metre). JAX_068, dense start, 1000 steps at half resolution: with it
  // MAE 1.49 m, 131k Gaussians, 21.3-22.3 dB, 540-591 s of training; without
  // it 1.36 m, 67k Gaussians, 22.2 dB, 399 s.
  std::string densify = "auto";
};

// Trains (resuming from out_dir/checkpoints when possible), then writes
// scene.ply and train_report.json.
TrainResult RunTrainJob(TrainJob job, Progress& progress);

}  // namespace skyfall::cli
