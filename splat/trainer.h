// The Skyfall-GS reconstruction stage on a CPU: 3DGS optimization of a
// Gaussian cloud initialized from the SfM points, with the paper's loss
// (L_color with lambda_DSSIM 0.2, entropy opacity regularization) and
// settings (scaling learning rate 0.001, pruning of huge Gaussians),
// adaptive density control, held-out evaluation and resumable checkpoints.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/gaussians.h"
#include "core/option_range.h"
#include "core/pinhole.h"
#include "core/stage.h"
#include "splat/appearance.h"
#include "splat/density_control.h"
#include "splat/depth_prior.h"
#include "splat/rasterizer.h"

namespace skyfall {

struct TrainView {
  std::string name;
  PinholeCamera camera;       // for the (possibly downscaled) image
  std::vector<float> rgb;     // 3 per pixel in [0, 1]
  // 1 per pixel, 0 where the image holds no data (nodata, zero fill): those
  // pixels give no gradient. Empty: every pixel holds data.
  std::vector<std::uint8_t> valid;
  bool held_out = false;      // evaluation only
  std::string acquisition_time;  // ISO 8601 (UTC) when known, else empty
  SunDirection sun;              // the sun at acquisition, when known
  // Synthetic views (the synthesis stage's refined orbit renders) are drawn
  // with TrainOptions::synthetic_fraction and never anchored to the surface.
  bool synthetic = false;
  // Further colour targets of the same view (the refined samples beyond the
  // first): the photometric loss is the mean over `rgb` and these, so the
  // optimization settles on their consensus.
  std::vector<std::vector<float>> extra_rgb;
  // Depth target of the Pearson depth loss (lambda_view_depth), any affine
  // scale, NaN where there is none; empty: no depth loss on this view.
  std::vector<float> depth_target;
};

// Distinct acquisition dates (YYYY-MM-DD) among the training views; views
// without a time count as one unknown date.
int DistinctAcquisitionDates(const std::vector<TrainView>& views);

// Adam learning rates (3DGS defaults; scaling 0.001 as in the paper).
struct TrainLearningRates {
  double mean_initial = 1.6e-4;  // times the scene extent; decays exponentially...
  double mean_final = 1.6e-6;    // ...to this, times the extent
  // A larger rate renders held-out views better over 1000 steps but does
  // not keep the DSM's accuracy across scenes: the DSM comes first
  // (decision D-085).
  double scale = 0.001;
  // From the share scale_late_from of the steps on, the scales' rate is
  // scale_late instead (0: scale throughout). With the DSMs read before it
  // (TrainOptions::surface_at), the faster rate serves the views alone
  // (decision D-139).
  double scale_late = 0.012;
  double scale_late_from = 0.5;
  double rotation = 0.001;
  double opacity = 0.05;
  double sh_dc = 0.0025;
  double sh_rest = 0.0025 / 20;
};

// Anchoring to a known surface (needs a surface, e.g. the dense heights): on
// every training view, lambda_depth times the Huber loss (scale huber_m) of
// the expected depth against the surface's depth, and lambda_alpha times
// (1 - accumulated opacity), both averaged over the pixels that see the
// surface. The photometric loss alone lets Gaussians drift off the surface
// and fade (the DSM then loses accuracy and completeness); the Pearson depth
// loss cannot hold absolute heights.
struct TrainSurfaceOptions {
  double lambda_depth = 1.0;  // per metre of depth error
  double lambda_alpha = 0.5;
  double huber_m = 1.0;       // [m] errors beyond this count linearly
  // And each Gaussian whose centre is within height_band_m of the surface
  // height below it: lambda_height times half its squared height error
  // (SurfaceHeightLoss), weighted like the anchor's depth. The anchor holds
  // the blend of a pixel's Gaussians, not each centre, and the DSM is read
  // from centres (decision D-046).
  double lambda_height = 10.0;  // per m^2, averaged over the Gaussians
  double height_band_m = 1.0;
  // Every this many iterations the anchor also holds a nadir view of a patch
  // (the view the DSM is exported from; the satellite views alone leave its
  // coverage free to thin out): 0 = never.
  int nadir_interval = 2;
  int nadir_size_px = 192;
  double nadir_gsd_m = 0.5;
};

struct TrainOptions {
  int iterations = 1000;
  std::uint64_t seed = 1;
  double lambda_dssim = 0.2;
  double lambda_opacity = 10.0;     // entropy regularization weight (0 disables)
  // The entropy term starts once the photometric loss has lifted the useful
  // Gaussians' opacities (they start at 0.1, nearer the 0 pole): from the
  // first iteration it would drive every opacity to 0.
  int opacity_reg_from = 1000;
  TrainLearningRates lr;
  DensityControlOptions density;  // adaptive density control (clone, split, prune)
  // Bookkeeping.
  int eval_interval = 250;        // held-out PSNR into the report
  int checkpoint_interval = 500;  // resumable state
  // Also keep scene_<iteration>.ply in <checkpoint_dir>/snapshots at every
  // checkpoint, so that DSM error can be measured against run time.
  bool keep_snapshots = false;
  // The scene at this share of the steps is also kept as the DSMs' surface
  // (TrainResult::surface): the geometry has settled by then (decision
  // D-135), and the later steps, at lr.scale_late, serve the views. 0: the
  // DSMs come from the final scene.
  double surface_at = 0.5;
  // Pseudo-camera depth supervision (needs a DepthPrior): every
  // `pseudo_interval` iterations a pseudo view adds lambda_depth * (1 - |r|).
  double lambda_depth = 0.5;
  int pseudo_interval = 4;  // 0 disables; needs a DepthPrior to take effect
  PseudoCameraOptions pseudo;
  TrainSurfaceOptions surface;  // holding the Gaussians to a known surface (the dense heights)
  // Synthesis stage: the share of iterations that draw a synthetic view
  // when there are any (paper: 75 % refined views, 25 % satellite views),
  // and the weight of the Pearson depth loss on views with a depth target.
  double synthetic_fraction = 0.75;
  double lambda_view_depth = 0.5;
  // Per-image appearance (multi-date imagery). The exported cloud is fused
  // with the embedding of `appearance_image` (a training view name; empty:
  // the view whose embedding is nearest the mean).
  AppearanceOptions appearance;
  std::string appearance_image;
  RasterOptions raster;
  void Check() const;  // throws Error("train", field, ...)
};

// The optimizer's options as the run lists them (train.* in run_config.json).
template <class IO> void Visit(IO& io, TrainOptions& t) {
  // Set by the synthesis stage for its episodes from idu.* (IduOptions).
  io.NotAnOption(t.synthetic_fraction);
  io.NotAnOption(t.lambda_view_depth);
  io("iterations", t.iterations,
     "Splat training steps per tile", range::AtLeast(1));
  io("seed", t.seed,
     "Random seed of training");
  io("lambda_dssim", t.lambda_dssim,
     "Weight of the (1 - SSIM) term of the photometric loss; L1 weighs 1 minus this", range::In(0, 1));
  io("lambda_opacity", t.lambda_opacity,
     "Weight of the entropy opacity regularization; 0 = off", range::AtLeast(0));
  io("opacity_reg_from", t.opacity_reg_from,
     "First step of the entropy opacity term", range::AtLeast(0));
  io("lr_mean_initial", t.lr.mean_initial,
     "Adam learning rate of the centres at the first step, times the scene extent; it decays exponentially to "
     "lr_mean_final", range::Above(0));
  io("lr_mean_final", t.lr.mean_final,
     "Learning rate of the centres at the last step, times the scene extent", range::Above(0));
  io("lr_scale", t.lr.scale,
     "Adam learning rate of the Gaussians' scales", range::Above(0));
  io("lr_scale_late", t.lr.scale_late,
     "From lr_scale_late_from of the steps on, the scales' learning rate is this; 0 = lr_scale throughout",
     range::AtLeast(0));
  io("lr_scale_late_from", t.lr.scale_late_from,
     "Share of the steps after which lr_scale_late applies", range::In(0, 1));
  io("lr_rotation", t.lr.rotation,
     "Adam learning rate of the Gaussians' rotations", range::Above(0));
  io("lr_opacity", t.lr.opacity,
     "Adam learning rate of the Gaussians' opacities", range::Above(0));
  io("lr_sh_dc", t.lr.sh_dc,
     "Adam learning rate of the degree-0 spherical-harmonics colour", range::Above(0));
  io("lr_sh_rest", t.lr.sh_rest,
     "Adam learning rate of the higher spherical-harmonics coefficients", range::Above(0));
  Visit(io, t.density);
  io("eval_interval", t.eval_interval,
     "Steps between held-out PSNR evaluations, recorded in the report", range::AtLeast(1));
  io("checkpoint_interval", t.checkpoint_interval,
     "Steps between resumable checkpoints", range::AtLeast(1));
  io("keep_snapshots", t.keep_snapshots,
     "Also keep scene_<iteration>.ply under checkpoints/snapshots at every checkpoint (for skyfall report)");
  io("surface_at", t.surface_at,
     "Share of the steps at which the scene is also kept as the DSMs' surface (splat/surface.ply); 0 = the DSMs "
     "come from the final scene",
     range::In(0, 1));
  io("lambda_depth", t.lambda_depth,
     "Weight of the pseudo views' Pearson depth loss", range::AtLeast(0));
  io("pseudo_interval", t.pseudo_interval,
     "Steps between pseudo views; 0 = none (takes effect only with a depth prior)", range::AtLeast(0));
  io("pseudo_cameras", t.pseudo);
  io("lambda_surface_depth", t.surface.lambda_depth,
     "Weight of the surface anchor's Huber depth loss, per metre of depth error; 0 = off", range::AtLeast(0));
  io("lambda_surface_alpha", t.surface.lambda_alpha,
     "Weight of the surface anchor's (1 - accumulated opacity) term where the surface is seen; 0 = off",
     range::AtLeast(0));
  io("surface_huber_m", t.surface.huber_m,
     "Scale of the surface anchor's Huber loss: depth errors beyond it count linearly", range::Above(0));
  io("lambda_surface_height", t.surface.lambda_height,
     "Weight of the loss that holds Gaussian centres near the dense surface to its height, per m^2 and averaged over "
     "the Gaussians; 0 = off", range::AtLeast(0));
  io("surface_height_band_m", t.surface.height_band_m,
     "Gaussians whose centre is within this of the surface height below it are held by lambda_surface_height",
     range::Above(0));
  io("surface_nadir_interval", t.surface.nadir_interval,
     "Steps between the nadir patches the surface anchor also holds; 0 = never", range::AtLeast(0));
  io("surface_nadir_size_px", t.surface.nadir_size_px,
     "Side of the surface anchor's square nadir patch", range::AtLeast(16));
  io("surface_nadir_gsd_m", t.surface.nadir_gsd_m,
     "Ground pixel size of the surface anchor's nadir patch", range::Above(0));
  io("appearance_model", t.appearance);
  io("appearance_image", t.appearance_image,
     "Training view whose appearance is fused into scene.ply (empty = the view whose embedding is nearest the mean)");
  io("raster", t.raster);
}

// One point of the error-versus-time series.
struct TrainSample {
  int iteration = 0;
  double seconds = 0;
  double loss = 0;          // mean training loss since the previous sample
  double psnr_test_db = 0;  // mean over held-out views (NaN when there are none); with the
                            // appearance model, rendered with the mean training embedding
  std::size_t gaussians = 0;
};

// Where the time of the training steps went, summed over the steps of this
// run (a resumed run counts only its own steps). Phases: the appearance
// model (forward and backward), the main view's rasterizer forward and
// backward, its losses (photometric, depth, anchor, opacity), the extra
// regularizer views (nadir anchor patches, pseudo views: their rendering
// and backward), the optimizer (Adam and the densification statistics),
// densification, held-out evaluation, and bookkeeping (checkpoints,
// progress, freeing the step's buffers).
struct StepProfile {
  static constexpr const char* kPhases[] = {"appearance", "raster_fwd", "loss",     "raster_bwd", "regularizer_views",
                                            "optimizer",  "densify",    "evaluation", "bookkeeping"};
  static constexpr int kCount = 9;
  double seconds[kCount] = {};
  int steps = 0;
  // Mean milliseconds per step of phase `k`, and of the whole step.
  double MeanMs(int k) const { return steps ? 1e3 * seconds[k] / steps : 0.0; }
  double StepMs() const;
  // ("step", StepMs()) then (phase, MeanMs) for every phase, for reports.
  std::vector<std::pair<std::string, double>> MeanMsByPhase() const;
};

// A held-out view as the trained model renders it (with the embedding its
// date chooses), and its scores: what the held-out PSNR averages.
struct HeldOutRender {
  std::string name;
  int width_px = 0, height_px = 0;
  std::vector<float> rgb;     // the render, 3 per pixel in [0, 1]
  std::vector<float> target;  // the view's own image
  double psnr_db = 0;
  double fitted_psnr_db = 0;  // colours fitted on the left half, scored on the right
  // Sat-NeRF's protocol: the view rendered with each training view's
  // embedding, scored with the best (chosen against the view's own pixels;
  // without the appearance model, psnr_db).
  double best_embedding_psnr_db = 0;
  std::string best_embedding_view;  // whose embedding that was (empty without the model)
};

struct TrainResult {
  GaussianCloud cloud;      // plain 3DGS; with appearance, fused for `appearance_image`
  std::string appearance_image;  // the view whose appearance was fused (empty without the model)
  std::vector<TrainSample> series;
  std::vector<HeldOutRender> held_out;  // after the last step
  // With TrainOptions::surface_at: the cloud (exported like `cloud`) at that
  // step, the DSMs' surface; its step in surface_iteration.
  std::optional<GaussianCloud> surface;
  int surface_iteration = 0;
  int start_iteration = 0;  // > 0 when resumed from a checkpoint
  StepProfile profile;
  StageReport report;
};

// Gaussians at the SfM points: colour from the points, isotropic scale from
// the mean distance d to the 3 nearest neighbours (at most `max_scale_m`),
// opacity 0.1. Where the cap leaves a point's Gaussian smaller than its
// neighbourhood, up to `max_pieces_per_point` Gaussians of the capped size
// share it: (d / cap)^2 of them, spread over a horizontal disc of radius d/2
// at the point's height (ENU: z is up), so capped Gaussians still cover the
// surface between sparse points. Deterministic.
GaussianCloud InitializeFromPoints(const std::vector<Eigen::Vector3f>& points,
                                   const std::vector<Eigen::Vector3f>& colours_01,
                                   double max_scale_m = std::numeric_limits<double>::infinity(),
                                   int max_pieces_per_point = 1);

// Zeroes all gradients of every Gaussian that has a non-finite one (NaN or
// infinite, any field) and returns how many Gaussians that was. One such
// gradient would make the Gaussian's parameters NaN for good (Adam carries
// it into its moments) and, through the renders, the loss of later steps;
// the step goes on for the others, and the train report counts them.
// Also zeroes their colour-transform gradients (`g->d_colour_affine`, when
// there are any), which the appearance model's gradient is built from.
std::size_t DropNonFiniteGradients(GaussianGradients<float>* g);

// How many Gaussians have their centre within `within_m` of another one's:
// Gaussians that training drew onto one point add cost but no geometry (the
// train report's coincident_gaussians, at 1 cm).
std::size_t CoincidentGaussians(const GaussianCloud& cloud, double within_m);

// Trains `cloud` on the views. With a non-empty `checkpoint_dir`, state is
// saved there every checkpoint_interval iterations and a matching checkpoint
// is resumed from.
// `depth_prior` may be null (no depth supervision).
// `surface` may be null (no anchoring); it is ray-cast once per training view.
TrainResult TrainGaussians(const TrainOptions& options, GaussianCloud cloud, const std::vector<TrainView>& views,
                           const std::string& checkpoint_dir, Progress& progress, DepthPrior* depth_prior = nullptr,
                           const SurfaceDepthPrior* surface = nullptr);

}  // namespace skyfall
