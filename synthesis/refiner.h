// Refiners of the synthesis stage: a rendered orbit view in, N_s refined
// images out (Skyfall-GS uses FlowEdit with FLUX.1 [dev], whose weights
// cannot be had here). `reproject` needs no weights; `cmd:COMMAND` runs a
// user's program (for example a FlowEdit script) over a folder of renders.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/enum_codec.h"
#include "core/gaussians.h"
#include "core/option_range.h"
#include "core/pinhole.h"
#include "core/stage.h"
#include "splat/depth_prior.h"
#include "splat/trainer.h"

namespace skyfall {

// One rendered orbit view.
struct RefineInput {
  std::string name;               // unique; the file stem for external refiners
  PinholeCamera camera;
  std::vector<float> rgb;         // 3 per pixel in [0, 1]
  std::vector<float> depth_m;     // camera depth [m] of the surface the pixel shows, NaN where there is none
  double elevation_deg = 0, azimuth_deg = 0;
};

// What the refiner is asked for. The prompts and FlowEdit settings mean
// something only to diffusion refiners; they travel to external ones as is
// (paper values: n_min 4, n_max 10; FlowEdit's FLUX defaults for the rest).
struct RefineRequest {
  int samples = 2;                 // N_s refined images per view (paper: 2)
  std::uint64_t seed = 1;          // sample k of view v uses seed + 1000 * v + k
  int episode = 0;
  std::string source_prompt =
      "Satellite image of an urban area with modern and older buildings, roads, green spaces. Some areas appear "
      "distorted, with blurring and warping artifacts.";
  std::string target_prompt =
      "Clear satellite image of an urban area with sharp buildings, smooth edges, natural lighting, and "
      "well-defined textures.";
  int n_min = 4, n_max = 10, n_avg = 1, steps = 28;
  double source_guidance_scale = 1.5, target_guidance_scale = 5.5;
};
template <class IO> void Visit(IO& io, RefineRequest& o) {
  // Set per episode by the synthesis stage from its own options (idu.samples, idu.seed).
  io.NotAnOption(o.samples);
  io.NotAnOption(o.seed);
  io.NotAnOption(o.episode);
  io("source_prompt", o.source_prompt,
     "Prompt that describes the rendered views, for external (diffusion) refiners");
  io("target_prompt", o.target_prompt,
     "Prompt that describes the refined views wanted, for external (diffusion) refiners");
  io("n_min", o.n_min,
     "FlowEdit's n_min, for external refiners: the last this many steps are plain sampling with the target prompt",
     range::AtLeast(0));
  io("n_max", o.n_max,
     "FlowEdit's n_max, for external refiners: editing starts this many steps before the end", range::AtLeast(0));
  io("n_avg", o.n_avg,
     "FlowEdit's n_avg, for external refiners: noise samples averaged per step", range::AtLeast(1));
  io("steps", o.steps,
     "Diffusion sampling steps, for external refiners", range::AtLeast(1));
  io("source_guidance_scale", o.source_guidance_scale,
     "Classifier-free guidance scale of the source prompt, for external refiners", range::AtLeast(0));
  io("target_guidance_scale", o.target_guidance_scale,
     "Classifier-free guidance scale of the target prompt, for external refiners", range::AtLeast(0));
}

using RefinedSamples = std::vector<std::vector<float>>;  // N_s images, 3 floats per pixel in [0, 1]

class Refiner {
 public:
  virtual ~Refiner() = default;
  // `scene`: the model the views were rendered from. Returns, per view, its samples.
  virtual std::vector<RefinedSamples> Refine(const GaussianCloud& scene, const std::vector<RefineInput>& views,
                                             const RefineRequest& request, Progress& progress) = 0;
};

// What fills orbit pixels no satellite view sees (ReprojectOptions::inpaint).
enum class Inpaint { kTelea, kNavierStokes, kRender };
template <>
struct EnumNames<Inpaint> {
  static constexpr std::array<std::pair<Inpaint, const char*>, 3> kNames = {
      {{Inpaint::kTelea, "telea"}, {Inpaint::kNavierStokes, "ns"}, {Inpaint::kRender, "render"}}};
};

struct ReprojectOptions {
  // A satellite view sees an orbit pixel's surface point when the point's
  // depth in that view is within this of the depth the scene renders there:
  // above the Gaussian surface's noise (~0.5 m), below a storey (~3 m).
  double visibility_tolerance_m = 1.5;
  // Weight of a satellite view: (cos of the angle between its ray and the
  // orbit ray at the point)^this, so views from similar directions count most.
  double angle_weight_power = 4.0;
  // Each sample keeps each satellite view with this probability (at least
  // one), with its weight scaled by a factor drawn from [1 - j, 1 + j].
  double keep_probability = 0.7;
  double weight_jitter = 0.5;
  // Pixels no satellite view sees: "telea" or "ns" (OpenCV inpainting) or
  // "render" (keep the rendered colour).
  Inpaint inpaint = Inpaint::kTelea;
  double inpaint_radius_px = 3.0;
  // Edge-preserving smoothing at the end (bilateral filter; 0 = off).
  int smooth_diameter_px = 5;
  double smooth_sigma_colour = 0.08;  // [0-1 colour units]
  double smooth_sigma_space_px = 2.0;
  void Check() const;                 // throws Error("idu", field, ...)
};
template <class IO> void Visit(IO& io, ReprojectOptions& o) {
  io("visibility_tolerance_m", o.visibility_tolerance_m,
     "A satellite view sees an orbit pixel's surface point when the point's depth in that view is within this of the "
     "depth the scene renders there", range::Above(0));
  io("angle_weight_power", o.angle_weight_power,
     "A satellite view weighs (cos of the angle between its ray and the orbit ray)^this, so views from similar "
     "directions count most", range::AtLeast(0));
  io("keep_probability", o.keep_probability,
     "Each sample keeps each satellite view with this probability (at least one view is kept)", range::AboveUpTo(0, 1));
  io("weight_jitter", o.weight_jitter,
     "Each kept view's weight is scaled by a factor drawn from [1 - this, 1 + this]", range::FromBelow(0, 1));
  io("inpaint", o.inpaint,
     "Pixels no satellite view sees: 'telea' or 'ns' (OpenCV inpainting) or 'render' (the rendered colour is kept)");
  io("inpaint_radius_px", o.inpaint_radius_px,
     "Radius of the OpenCV inpainting", range::Above(0));
  io("smooth_diameter_px", o.smooth_diameter_px,
     "Diameter of the final edge-preserving bilateral filter; 0 = off", range::In(0, 31));
  io("smooth_sigma_colour", o.smooth_sigma_colour,
     "Colour sigma of the bilateral filter, in colour units of 0 to 1", range::Above(0));
  io("smooth_sigma_space_px", o.smooth_sigma_space_px,
     "Spatial sigma of the bilateral filter", range::Above(0));
}

// Built-in refiner without model weights: each orbit pixel with a surface
// takes the robust (weighted median) colour of the satellite views that see
// its 3D point, so what the satellites saw sharply replaces the blurred
// render; pixels no view sees are inpainted, then the image is smoothed
// preserving edges. Samples differ by the subset and weights of the views.
class ReprojectRefiner final : public Refiner {
 public:
  // `satellite`: the satellite training views (colours and cameras).
  // Orbit pixels lie at RefineInput::depth_m. `surface` (may be null): a
  // height field (the dense heights) whose ray-cast depth, vertical walls
  // included, decides satellite visibility where it has an answer;
  // elsewhere the depth the scene renders does. The Gaussians of a
  // satellite reconstruction hardly hold facades, the height field's steps
  // do (the caller places orbit pixels on the same field, see RunIdu).
  ReprojectRefiner(const std::vector<TrainView>& satellite, ReprojectOptions options, RasterOptions raster = {},
                   const SurfaceDepthPrior* surface = nullptr);
  std::vector<RefinedSamples> Refine(const GaussianCloud& scene, const std::vector<RefineInput>& views,
                                     const RefineRequest& request, Progress& progress) override;

 private:
  const std::vector<TrainView>& satellite_;
  ReprojectOptions options_;
  RasterOptions raster_;
  const SurfaceDepthPrior* surface_;
  std::vector<DepthMap> surface_in_satellite_;  // the surface's depth in each satellite view (computed once)
  std::vector<Eigen::Vector3d> satellite_centres_;  // world position of each satellite camera
};

// External refiner: for each call, writes the renders as IN/<name>.png and
// IN/request.json (the RefineRequest, each view's name, file, size,
// elevation, azimuth and per-sample seeds), runs `COMMAND IN OUT` with
// /bin/sh, and reads OUT/<name>_s<k>.png (k = 0 .. samples-1, 8-bit RGB or
// grey, the render's size). Folders live under `work_dir`/episode_<e>.
class CommandRefiner final : public Refiner {
 public:
  CommandRefiner(std::string command, std::string work_dir);
  std::vector<RefinedSamples> Refine(const GaussianCloud& scene, const std::vector<RefineInput>& views,
                                     const RefineRequest& request, Progress& progress) override;

 private:
  std::string command_;
  std::string work_dir_;
};

// "reproject" or "cmd:COMMAND"; throws Error naming `field` otherwise.
std::unique_ptr<Refiner> MakeRefiner(const std::string& spec, const std::vector<TrainView>& satellite,
                                     const ReprojectOptions& reproject, const std::string& work_dir,
                                     const std::string& field, const SurfaceDepthPrior* surface = nullptr);

// The seed of sample k of view v in a request.
inline std::uint64_t SampleSeed(const RefineRequest& r, std::size_t view, int sample) {
  return r.seed + 1000ull * view + static_cast<std::uint64_t>(sample);
}

}  // namespace skyfall
