// The synthesis stage of Skyfall-GS: the curriculum iterative dataset update
// (IDU, paper Sec. 3.2 and Algorithm 1). Over N_e episodes with falling
// elevation it renders orbit views of the current scene, refines each render
// N_s times, and trains on the refined views mixed with the satellite views
// (75 / 25), with L_color averaged over the samples plus lambda_depth times
// the Pearson depth loss against the depth rendered at the episode's start.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/enum_codec.h"
#include "core/gaussians.h"
#include "core/option_range.h"
#include "core/stage.h"
#include "core/tile.h"
#include "splat/depth_prior.h"
#include "splat/trainer.h"
#include "synthesis/orbit.h"
#include "synthesis/refiner.h"

namespace skyfall {

// Where refined views get their geometry (IduOptions::geometry).
enum class IduGeometry { kSurface, kRender };
template <>
struct EnumNames<IduGeometry> {
  static constexpr std::array<std::pair<IduGeometry, const char*>, 2> kNames = {
      {{IduGeometry::kSurface, "surface"}, {IduGeometry::kRender, "render"}}};
};

struct IduOptions {
  OrbitOptions orbit;
  // Training iterations per episode (paper: 10,000 on a GPU; a CPU tile
  // affords a few hundred within the stage-time budget of at most twice the
  // reconstruction; decisions D-043 and D-130).
  int iterations_per_episode = 150;
  int samples = 2;                    // N_s refined samples per view (paper: 2)
  double synthetic_fraction = 0.75;   // share of iterations on refined views (paper: 75 %)
  double lambda_depth = 0.5;          // Pearson depth loss on refined views
  // Entropy opacity regularization during the episodes (the paper turns it
  // off for IDU: 0).
  double lambda_opacity = 0.0;
  // Densification within each episode (paper: through 90 % of it), from
  // densify_from_fraction of the episode every densify_interval iterations.
  // Off by default: it buys a little at oblique views but costs DSM
  // accuracy and time (decision D-024).
  bool densify = false;
  double densify_from_fraction = 0.2;
  double densify_until_fraction = 0.9;
  int densify_interval = 100;
  // Where refined views get their geometry: "surface" (the height field of
  // the dense heights, vertical walls included, where it has an answer: the
  // depth target of the Pearson loss and the surface anchor on refined views)
  // or "render" (the paper: the depth the scene renders at the episode's
  // start). The Gaussians of a satellite reconstruction hardly hold facades;
  // the paper's diffusion refiner paints them in, a reprojecting one cannot.
  IduGeometry geometry = IduGeometry::kSurface;
  // (Holding refined views to the height field with the surface anchor was
  // tried and not adopted: decision D-024.)
  // With geometry "surface": orbit pixels where the height field has a
  // surface but the scene renders transparent (walls the reconstruction left
  // as holes) are refined and trained on too, and each episode adds a
  // Gaussian of the refined colour at those surface points, one per
  // fill_voxel_m cube. Without it such holes are masked from training and,
  // with densification off, stay holes. 1 m cubes: nearly the oblique
  // views of 0.5 m cubes with far fewer Gaussians (decision D-043).
  bool fill_holes = true;
  // (Holding the reconstruction's geometry through the episodes, training
  // only its colours, was tried and not adopted: decision D-054.)
  double fill_voxel_m = 1.0;
  std::uint64_t seed = 1;
  RefineRequest request;              // prompts and FlowEdit settings for external refiners
  void Check() const;                 // throws Error("idu", field, ...)
};

// As the run lists them (idu.* in run_config.json).
template <class IO> void Visit(IO& io, IduOptions& i) {
  io("orbit", i.orbit);
  io("iterations_per_episode", i.iterations_per_episode,
     "Training steps per episode", range::AtLeast(1));
  io("samples", i.samples,
     "Refined images per orbit view", range::In(1, 16));
  io("synthetic_fraction", i.synthetic_fraction,
     "Share of the training steps on refined views; the others use satellite views", range::In(0, 1));
  io("lambda_depth", i.lambda_depth,
     "Weight of the Pearson depth loss on refined views", range::AtLeast(0));
  io("lambda_opacity", i.lambda_opacity,
     "Weight of the entropy opacity regularization during the episodes; 0 = off", range::AtLeast(0));
  io("densify", i.densify,
     "Adaptive density control (clone, split, prune) within each episode");
  io("densify_from_fraction", i.densify_from_fraction,
     "Densification starts at this fraction of each episode", range::In(0, 1));
  io("densify_until_fraction", i.densify_until_fraction,
     "Densification ends at this fraction of each episode", range::In(0, 1));
  io("densify_interval", i.densify_interval,
     "Steps between densification passes within an episode", range::AtLeast(1));
  io("geometry", i.geometry,
     "Where refined views get their geometry: 'surface' (the dense heights' height field, walls included) or "
     "'render' (the depth the scene renders at the episode's start)");
  io("fill_holes", i.fill_holes,
     "With geometry 'surface', also refine and train on orbit pixels where the height field has a surface but the "
     "scene is transparent, adding Gaussians there");
  io("fill_voxel_m", i.fill_voxel_m,
     "Edge of the cubes in which fill_holes adds one Gaussian each", range::Above(0));
  io("seed", i.seed,
     "Random seed of the stage's training and refined samples");
  io("prompts", i.request);
}

struct IduEpisode {
  int episode = 0;
  double elevation_deg = 0, radius_m = 0;
  int views = 0;
  double render_seconds = 0, refine_seconds = 0, train_seconds = 0;
  double refined_coverage = 0;        // share of orbit pixels with a surface (trained on)
  double psnr_test_start_db = 0;      // held-out satellite PSNR of the scene the episode started from
  double psnr_test_db = 0;            // held-out satellite PSNR after the episode (NaN: none held out)
  std::size_t gaussians = 0;
  std::size_t hole_gaussians = 0;     // added at the start of the episode where the scene had holes
  std::vector<std::pair<std::string, double>> step_ms;  // mean per training step, by phase (StepProfile)
  bool reused = false;                // finished by an earlier, killed run
};

// The episodes as a JSON array (the fields of IduEpisode), for reports.
std::string IduEpisodesJson(const std::vector<IduEpisode>& episodes);

struct IduResult {
  GaussianCloud cloud;
  std::vector<IduEpisode> episodes;
  StageReport report;
};

// Runs the episodes on `cloud` (the reconstruction, plain 3DGS colours).
// `train`: the reconstruction's optimizer settings (learning rates, raster,
// surface anchor), adapted per episode (iterations, no opacity entropy as in
// the paper, no appearance model: one fixed appearance). `surface` (may be
// null), the dense heights' height field: with geometry "surface" it places
// the refined views' pixels, and the reconstruction's surface anchor (when
// its weights are not 0) holds the satellite views to it. In
// `out_dir`: episode_<k>/ with the orbit cameras, renders, refined samples
// and scene.ply, and episode.json written last; a rerun with the same
// `options_json` resumes after the last finished episode.
IduResult RunIdu(const IduOptions& options, const TrainOptions& train, GaussianCloud cloud,
                 const std::vector<TrainView>& satellite, const GroundBox& core, const GeodeticPoint& enu_origin,
                 const std::function<double(double, double)>& surface_height_m, const SurfaceDepthPrior* surface,
                 Refiner& refiner, const std::string& out_dir, const std::string& options_json, Progress& progress);

// The satellite views' colours carried to the scene's one appearance: each
// view's channels mapped by the gain and offset that best fit (least
// squares, over the pixels with data where the render is opaque) the scene
// rendered from that view. The reconstruction's plain colours are those of
// one image (the appearance it was fused for); satellite views of other
// dates would otherwise pull the stage's refined views, and the scene
// trained on them, towards a mix of dates. Views with too few opaque pixels
// (under a tenth) or a flat channel keep their colours.
std::vector<TrainView> MatchSceneAppearance(const GaussianCloud& scene, std::vector<TrainView> views,
                                            const RasterOptions& raster);

// `--idu auto`: whether the stage can help a tile, from its dense heights.
struct IduAutoOptions {
  double step_m = 3.0;                 // a height step between neighbouring cells this tall or taller is a facade
  double min_facade_ratio = 0.02;      // [m^2 of facade per m^2 of ground] below: flat or low-rise, skipped
  double min_measured_fraction = 0.05; // below: water, featureless or empty, skipped
  void Check() const;
};
template <class IO> void Visit(IO& io, IduAutoOptions& o) {
  io("step_m", o.step_m,
     "A height step between neighbouring dense cells at least this tall counts as a facade", range::Above(0));
  io("min_facade_ratio", o.min_facade_ratio,
     "Tiles with less facade than this, in m^2 of facade per m^2 of ground, are flat or low-rise and skipped",
     range::AtLeast(0));
  io("min_measured_fraction", o.min_measured_fraction,
     "Tiles whose dense heights matched a smaller fraction of the grid (water, featureless or empty) are skipped",
     range::In(0, 1));
}

struct IduDecision {
  bool on = false;
  std::string why;
  double facade_ratio = 0;        // vertical facade area per ground area in the dense heights
  double measured_fraction = 0;   // share of grid cells measured (not filled)
};

// `mode`: on, off or auto (decided from the heights). `points`: the dense cells' ENU positions on
// a grid of `cell_m`, `filled`: which were filled rather than measured.
IduDecision DecideIdu(Switch mode, const IduAutoOptions& options, const std::vector<Eigen::Vector3f>& points,
                      const std::vector<std::uint8_t>& filled, double cell_m);

}  // namespace skyfall
