// Stage jobs: each reads its inputs from files, runs a library stage and
// writes its outputs atomically, so `skyfall splat train` on its own and a
// tile of `skyfall run` behave alike.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/aoi.h"
#include "core/stage.h"
#include "pipeline/run_options.h"
#include "pipeline/view_masks.h"
#include "dense/dense.h"
#include "dense/dense_cells.h"
#include "sfm/sfm.h"
#include "splat/trainer.h"

namespace skyfall {

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

// Per dense cell: whether the heights within reach_m of it differ by more
// than min_step_m (a step: a wall, a roof's edge). All 0 when reach_m is 0.
std::vector<std::uint8_t> CellsNearSteps(const DenseCells& cells, double reach_m, double min_step_m);

// Per cell confidence for SurfaceDepthPrior: 1, less for filled cells and
// for cells beside a step (AnchorWeightOptions); empty when every weight
// is 1 (no weighting).
std::vector<float> AnchorCellWeights(const DenseCells& cells, const AnchorWeightOptions& options);

// True when `sfm_dir` holds a finished dense stage over the same extent whose
// recorded options still hold (SettingsStillHold).
bool DenseDone(const std::string& sfm_dir, const DenseOptions& options, const std::optional<GroundBox>& extent_enu_m);

// The training images' downscale and why (asked for, or automatic from the
// finest view's GSD).
struct TrainDownscale {
  int factor = 2;
  double finest_gsd_m = 0;  // [m] 0 when asked for
  std::string why;
};

// `asked` (train.downscale) when positive, else the automatic factor for the
// finest GSD of the views in sfm_dir/cameras.json (core/ground_cell.h).
TrainDownscale ResolveTrainDownscale(int asked, const std::string& sfm_dir);

// The spacing of a dense start's Gaussians and where it came from:
// train.init_spacing_m, or automatic from the dense cell
// (InitSpacingForDenseCellM, core/ground_cell.h).
struct InitSpacing {
  double value_m = 0;
  std::string why;
};
InitSpacing InitSpacingM(const TrainStageOptions& stage, const DenseCells& dense);

// What the training job decided and why (for the reports).
struct TrainDecisions {
  TrainDownscale downscale;
  bool dense_start = false;
  InitSpacing init_spacing;  // with a dense start
  std::size_t init_fine_points = 0;  // dense cells kept beside steps (train.init_step_reach_m)
  bool densify = false;
  bool appearance = false;
  std::string appearance_reason;
  bool surface_anchor = false;  // training anchored to the dense heights (needs a dense start)
  double masked_beyond_fraction = 0;  // share of the views' pixels with data seeing past the dense heights
  bool cloud_mask = false;            // MaskClouds ran
  std::string cloud_mask_why;
  // Per training view (name), the share of its pixels with data masked as cloud.
  std::vector<std::pair<std::string, double>> cloud_masked_fraction;
};

// The masks of view_masks.h that `stage` asks for and the dense heights
// allow, applied to `views`; what was masked and why goes into `decided`,
// and, per view, 1 for each pixel masked as cloud into `cloudy` (empty for
// views with no cloud mask) when given.
void MaskViews(const TrainStageOptions& stage, const DenseCells& dense, const RasterOptions& raster,
               std::vector<TrainView>* views, TrainDecisions* decided,
               std::vector<std::vector<std::uint8_t>>* cloudy = nullptr);

struct TrainJobResult {
  TrainResult train;
  TrainDecisions decisions;
};

// Trains on the SfM folder `sfm_dir` (resuming from out_dir/checkpoints when
// the settings match, else setting the old checkpoint aside), then writes
// scene.ply and train_report.json into `out_dir`.
TrainJobResult RunTrainJob(const TrainStageOptions& options, const std::string& sfm_dir, const std::string& out_dir,
                           Progress& progress);

// The synthesis stage of a tile: decided from the dense heights of `sfm_dir`
// (IduStageOptions::mode), and when on, run on `scene_ply` with the training
// views of `sfm_dir`, writing out_dir/scene.ply and out_dir/idu_report.json
// (episodes resume under the same `episodes_stamp`, see IduEpisodesJson).
// When off, out_dir/scene.ply is removed, so the trained scene is the tile's.
struct IduJobResult {
  IduDecision decision;
  IduResult idu;  // empty when not run
};
IduJobResult RunIduJob(const IduStageOptions& options, const TrainStageOptions& train, const std::string& sfm_dir,
                       const std::string& scene_ply, const GroundBox& core, const std::string& out_dir,
                       const std::string& episodes_stamp, Progress& progress);

// Renders the scene (Inria PLY) from every camera of a cameras.json into
// out_dir: <name>_rgb.png, <name>_depth.png (visualization) and
// <name>_depth.tif (camera depth in metres, NaN where opacity < 0.5).
void RenderSceneJob(const std::string& scene_ply, const std::string& cameras_json, const std::string& out_dir,
                    int downscale, Progress& progress);

}  // namespace skyfall
