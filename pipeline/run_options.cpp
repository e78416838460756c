#include "pipeline/run_options.h"

#include <Eigen/Core>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <limits>
#include <set>
#include <type_traits>

#include "core/error.h"
#include "core/format.h"

namespace skyfall {
namespace {

using json = nlohmann::json;
constexpr const char* kSchema = "skyfall.run_options/1";

// Every options struct is described once, by a Visit() that names each field;
// the same description writes JSON and reads it strictly (Writer, Reader below).

template <class IO> void Visit(IO& io, RadiometryOptions& o) {
  io("low_percentile", o.low_percentile);
  io("high_percentile", o.high_percentile);
  io("stretch_byte", o.stretch_byte);
  io("max_sample_px", o.max_sample_px);
}
template <class IO> void Visit(IO& io, IngestOptions& o) {
  io("verify_pixels", o.verify_pixels);
  io("radiometry", o.radiometry);
  io("height_margin_m", o.height_margin_m);
  io("rpc_height_half_range_m", o.rpc_height_half_range_m);
  io("nominal_orbit_height_m", o.nominal_orbit_height_m);
  io("view_ray_height_step_m", o.view_ray_height_step_m);
}
template <class IO> void Visit(IO& io, TilingOptions& o) {
  io("tile_m", o.tile_m);
  io("tile_px", o.tile_px);
  io("overlap_m", o.overlap_m);
  io("min_coverage", o.min_coverage);
  io("min_images", o.min_images);
  io("city", o.city);
}
template <class IO> void Visit(IO& io, PinholeFitOptions& o) {
  io("grid_cols", o.grid_cols);
  io("grid_rows", o.grid_rows);
  io("grid_heights", o.grid_heights);
  io("check_cols", o.check_cols);
  io("check_rows", o.check_rows);
  io("check_heights", o.check_heights);
  io("hartley_normalization", o.hartley_normalization);
  io("refine", o.refine);
  io("estimate_skew", o.estimate_skew);
}
template <class IO> void Visit(IO& io, FeatureOptions& o) {
  io("max_features", o.max_features);
  io("contrast_threshold", o.contrast_threshold);
  io("ratio", o.ratio);
  io("clahe_clip", o.clahe_clip);
  io("stretch_low", o.stretch_low);
  io("stretch_high", o.stretch_high);
}
// The verification's height range comes from each catalog, so only its
// tolerances are options.
template <class IO> void Visit(IO& io, VerifyOptions& o) {
  io("min_threshold_px", o.min_threshold_px);
  io("mad_factor", o.mad_factor);
  io("segment_slack", o.segment_slack);
  io("height_pad_m", o.height_pad_m);
}
template <class IO> void Visit(IO& io, BundleOptions& o) {
  io("huber_px", o.huber_px);
  io("offset_prior_sigma_px", o.offset_prior_sigma_px);
  io("max_iterations", o.max_iterations);
}
template <class IO> void Visit(IO& io, SfmOptions& o) {
  io("pinhole", o.pinhole);
  io("features", o.features);
  io("verify", o.verify);
  io("bundle", o.bundle);
  io("min_matches_per_pair", o.min_matches_per_pair);
  io("min_observations_per_image", o.min_observations_per_image);
  io("max_reprojection_before_ba_px", o.max_reprojection_before_ba_px);
  io("max_reprojection_after_ba_px", o.max_reprojection_after_ba_px);
  io("min_triangulation_angle_deg", o.min_triangulation_angle_deg);
  io("ba_rounds", o.ba_rounds);
  io("anchor_image", o.anchor_image);
}
template <class IO> void Visit(IO& io, DenseOptions& o) {
  io("cell_m", o.cell_m);
  io("height_step_m", o.height_step_m);
  io("height_margin_m", o.height_margin_m);
  io("height_percentile", o.height_percentile);
  io("max_heights", o.max_heights);
  io("window_cells", o.window_cells);
  io("max_pairs", o.max_pairs);
  io("min_pair_matches", o.min_pair_matches);
  io("min_pair_angle_deg", o.min_pair_angle_deg);
  io("max_pair_angle_deg", o.max_pair_angle_deg);
  io("cost_truncation", o.cost_truncation);
  io("min_std", o.min_std);
  io("sgm_p1", o.sgm_p1);
  io("sgm_p2", o.sgm_p2);
  io("max_cost", o.max_cost);
  io("max_median_deviation_m", o.max_median_deviation_m);
  io("fill_holes", o.fill_holes);
  io("coarse_factor", o.coarse_factor);
  io("coarse_window_cells", o.coarse_window_cells);
  io("visibility_fill_seen_holes", o.visibility_fill_seen_holes);
  io("refine_steps", o.refine_steps);
  io("step_pull_run_cells", o.step_pull_run_cells);
  io("step_pull_min_m", o.step_pull_min_m);
  io("step_min_m", o.step_min_m);
  io("step_reach_cells", o.step_reach_cells);
  io("support_radius_cells", o.support_radius_cells);
  io("support_grey_sigma", o.support_grey_sigma);
  io("step_cost_margin", o.step_cost_margin);
  io("decide_filled_sides", o.decide_filled_sides);
  io("fill_radius_m", o.fill_radius_m);
  io("fill_roof_rim_fraction", o.fill_roof_rim_fraction);
  io("fill_roof_rim_occluded", o.fill_roof_rim_occluded);
  io("fill_roof_enclosed", o.fill_roof_enclosed);
  io("fill_far_raised_ground", o.fill_far_raised_ground);
  io("fill_seen_ground_terrain", o.fill_seen_ground_terrain);
  io("fill_edge_hides", o.fill_edge_hides);
  io("floating_patch_max_m2", o.floating_patch_max_m2);
  io("floating_patch_min_rise_m", o.floating_patch_min_rise_m);
  io("max_fill_reach_m", o.max_fill_reach_m);
  io("fill_ground_radius_m", o.fill_ground_radius_m);
  io("fill_ground_max_rise_m", o.fill_ground_max_rise_m);
  io("fill_ground_tolerance_m", o.fill_ground_tolerance_m);
  io("visibility_pass", o.visibility_pass);
  io("visibility_tolerance_m", o.visibility_tolerance_m);
  io("visibility_near_cells", o.visibility_near_cells);
  io("visibility_prior_pairs", o.visibility_prior_pairs);
}
template <class IO> void Visit(IO& io, PseudoCameraOptions& o) {
  io("radius_m", o.radius_m);
  io("look_at_sigma_m", o.look_at_sigma_m);
  io("min_elevation_deg", o.min_elevation_deg);
  io("max_elevation_deg", o.max_elevation_deg);
  io("size_px", o.size_px);
  io("fov_deg", o.fov_deg);
}
// `enabled` is decided by TrainStageOptions::appearance, so it is not listed.
template <class IO> void Visit(IO& io, AppearanceOptions& o) {
  io("model", o.model);
  io("image_dim", o.image_dim);
  io("gaussian_dim", o.gaussian_dim);
  io("hidden", o.hidden);
  io("lr_image", o.lr_image);
  io("lr_gaussian", o.lr_gaussian);
  io("lr_mlp", o.lr_mlp);
  io("init_std", o.init_std);
}
// `median_depth` is an output choice of each caller, not a training option.
template <class IO> void Visit(IO& io, RasterOptions& o) {
  io("tile_px", o.tile_px);
  io("min_alpha", o.min_alpha);
  io("max_alpha", o.max_alpha);
  io("min_transmittance", o.min_transmittance);
  io("dilation_px2", o.dilation_px2);
  io("near_m", o.near_m);
  io("guard_band", o.guard_band);
  io("sigma_extent", o.sigma_extent);
  io("sh_degree", o.sh_degree);
  io("background", o.background);
}
template <class IO> void Visit(IO& io, TrainStageOptions& o) {
  TrainOptions& t = o.optimizer;
  io("iterations", t.iterations);
  io("downscale", o.downscale);
  io("depth_prior", o.depth_prior);
  io("appearance", o.appearance);
  io("init_max_scale_m", o.init_max_scale_m);
  io("init_pieces", o.init_pieces);
  io("init_points", o.init_points);
  io("init_spacing_m", o.init_spacing_m);
  io("init_facade_step_m", o.init_facade_step_m);
  io("mask_beyond_reconstruction", o.mask_beyond_reconstruction);
  io("surface_filled_weight", o.anchor.filled_weight);
  io("surface_step_weight", o.anchor.step_weight);
  io("surface_step_reach_m", o.anchor.step_reach_m);
  io("surface_step_min_m", o.anchor.step_min_m);
  io("densify", o.densify);
  io("seed", t.seed);
  io("lambda_dssim", t.lambda_dssim);
  io("lambda_opacity", t.lambda_opacity);
  io("opacity_reg_from", t.opacity_reg_from);
  io("lr_mean_initial", t.lr_mean_initial);
  io("lr_mean_final", t.lr_mean_final);
  io("lr_scale", t.lr_scale);
  io("lr_rotation", t.lr_rotation);
  io("lr_opacity", t.lr_opacity);
  io("lr_sh_dc", t.lr_sh_dc);
  io("lr_sh_rest", t.lr_sh_rest);
  io("densify_from", t.densify_from);
  io("densify_until", t.densify_until);
  io("densify_interval", t.densify_interval);
  io("densify_grad_threshold", t.densify_grad_threshold);
  io("percent_dense", t.percent_dense);
  io("min_opacity", t.min_opacity);
  io("max_scale_m", t.max_scale_m);
  io("max_gaussians", t.max_gaussians);
  io("eval_interval", t.eval_interval);
  io("checkpoint_interval", t.checkpoint_interval);
  io("keep_snapshots", t.keep_snapshots);
  io("lambda_depth", t.lambda_depth);
  io("pseudo_interval", t.pseudo_interval);
  io("pseudo_cameras", t.pseudo);
  io("lambda_surface_depth", t.lambda_surface_depth);
  io("lambda_surface_alpha", t.lambda_surface_alpha);
  io("surface_huber_m", t.surface_huber_m);
  io("lambda_surface_height", t.lambda_surface_height);
  io("surface_height_band_m", t.surface_height_band_m);
  io("surface_nadir_interval", t.surface_nadir_interval);
  io("surface_nadir_size_px", t.surface_nadir_size_px);
  io("surface_nadir_gsd_m", t.surface_nadir_gsd_m);
  io("appearance_model", t.appearance);
  io("appearance_image", t.appearance_image);
  io("raster", t.raster);
}
template <class IO> void Visit(IO& io, OrbitOptions& o) {
  io("grid", o.grid);
  io("views_per_point", o.views_per_point);
  io("episodes", o.episodes);
  io("elevation_start_deg", o.elevation_start_deg);
  io("elevation_end_deg", o.elevation_end_deg);
  io("radius_start_per_core", o.radius_start_per_core);
  io("radius_end_per_core", o.radius_end_per_core);
  io("min_radius_m", o.min_radius_m);
  io("fov_deg", o.fov_deg);
  io("width_px", o.width_px);
  io("height_px", o.height_px);
}
template <class IO> void Visit(IO& io, RefineRequest& o) {
  io("source_prompt", o.source_prompt);
  io("target_prompt", o.target_prompt);
  io("n_min", o.n_min);
  io("n_max", o.n_max);
  io("n_avg", o.n_avg);
  io("steps", o.steps);
  io("source_guidance_scale", o.source_guidance_scale);
  io("target_guidance_scale", o.target_guidance_scale);
}
template <class IO> void Visit(IO& io, ReprojectOptions& o) {
  io("visibility_tolerance_m", o.visibility_tolerance_m);
  io("angle_weight_power", o.angle_weight_power);
  io("keep_probability", o.keep_probability);
  io("weight_jitter", o.weight_jitter);
  io("inpaint", o.inpaint);
  io("inpaint_radius_px", o.inpaint_radius_px);
  io("smooth_diameter_px", o.smooth_diameter_px);
  io("smooth_sigma_colour", o.smooth_sigma_colour);
  io("smooth_sigma_space_px", o.smooth_sigma_space_px);
}
template <class IO> void Visit(IO& io, IduAutoOptions& o) {
  io("step_m", o.step_m);
  io("min_facade_ratio", o.min_facade_ratio);
  io("min_measured_fraction", o.min_measured_fraction);
}
template <class IO> void Visit(IO& io, IduStageOptions& o) {
  IduOptions& i = o.options;
  io("mode", o.mode);
  io("refiner", o.refiner);
  io("orbit", i.orbit);
  io("iterations_per_episode", i.iterations_per_episode);
  io("samples", i.samples);
  io("synthetic_fraction", i.synthetic_fraction);
  io("lambda_depth", i.lambda_depth);
  io("lambda_opacity", i.lambda_opacity);
  io("densify", i.densify);
  io("densify_from_fraction", i.densify_from_fraction);
  io("densify_until_fraction", i.densify_until_fraction);
  io("densify_interval", i.densify_interval);
  io("geometry", i.geometry);
  io("anchor_refined_views", i.anchor_refined_views);
  io("fill_holes", i.fill_holes);
  io("fill_voxel_m", i.fill_voxel_m);
  io("hold_geometry", i.hold_geometry);
  io("seed", i.seed);
  io("prompts", i.request);
  io("reproject", o.reproject);
  io("auto", o.auto_decision);
}
template <class IO> void Visit(IO& io, SeamLineOptions& o) {
  io("enabled", o.enabled);
  io("cell_m", o.cell_m);
  io("band_fraction", o.band_fraction);
  io("max_step_m", o.max_step_m);
  io("bend_m", o.bend_m);
  io("centre_pull_m", o.centre_pull_m);
}
template <class IO> void Visit(IO& io, StitchOptions& o) {
  io("voxel_m", o.voxel_m);
  io("min_opacity", o.min_opacity);
  io("match_radius_voxels", o.match_radius_voxels);
  io("occupancy_columns", o.occupancy_columns);
  io("seam_lines", o.seam_lines);
}
template <class IO> void Visit(IO& io, LodOptions& o) {
  io("max_levels", o.max_levels);
  io("base_voxel_m", o.base_voxel_m);
  io("min_reduction", o.min_reduction);
  io("min_gaussians", o.min_gaussians);
}
template <class IO> void Visit(IO& io, MergeOptions& o) {
  io("stitch", o.stitch);
  io("lod", o.lod);
  io("seam_gsd_m", o.seam_gsd_m);
}
template <class IO> void Visit(IO& io, Tiles3dOptions& o) {
  io("leaf_m", o.leaf_m);
  io("max_fractional_bits", o.max_fractional_bits);
}
template <class IO> void Visit(IO& io, ExportOptions& o) {
  io("tiles3d", o.tiles3d);
  io("tiles3d_options", o.tiles3d_options);
}
template <class IO> void Visit(IO& io, DsmExportOptions& o) {
  io("camera_height_m", o.camera_height_m);
  io("min_alpha", o.min_alpha);
  io("median_depth", o.median_depth);
}
template <class IO> void Visit(IO& io, DsmCompareOptions& o) {
  io("max_shift_px", o.max_shift_px);
  io("pyramid_levels", o.pyramid_levels);
  io("mask_water", o.mask_water);
  io("within_m", o.within_m);
  io("rim_width_m", o.breakdown.rim_width_m);
  io("edge_band_m", o.breakdown.edge_band_m);
  io("edge_bands", o.breakdown.edge_bands);
}
template <class IO> void Visit(IO& io, DsmOptions& o) {
  io("source", o.source);
  io("export", o.export_options);
  io("compare", o.compare);
}
template <class IO> void Visit(IO& io, SlurmOptions& o) {
  io("partition", o.partition);
  io("account", o.account);
  io("time_limit", o.time_limit);
  io("cpus_per_task", o.cpus_per_task);
  io("mem_mb", o.mem_mb);
  io("poll_s", o.poll_s);
}
template <class IO> void Visit(IO& io, ExecutorOptions& o) {
  io("kind", o.kind);
  io("jobs", o.jobs);
  io("program", o.program);
  io("slurm", o.slurm);
}
template <class IO> void Visit(IO& io, RunOptions& o) {
  io("ingest", o.ingest);
  io("tiling", o.tiling);
  io("sfm", o.sfm);
  io("dense", o.dense);
  io("train", o.train);
  io("idu", o.idu);
  io("merge", o.merge);
  io("dsm", o.dsm);
  io("exports", o.exports);
  io("executor", o.executor);
}

template <class T>
constexpr bool kIsLeaf = std::is_arithmetic_v<T> || std::is_same_v<T, std::string> || std::is_same_v<T, Eigen::Vector3d>;

class Writer {
 public:
  explicit Writer(json* out) : out_(out) {}
  template <class T>
  void operator()(const char* key, const T& value) {
    if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
      (*out_)[key] = {value.x(), value.y(), value.z()};
    } else if constexpr (kIsLeaf<T>) {
      (*out_)[key] = value;
    } else {
      json nested = json::object();
      Writer inner(&nested);
      Visit(inner, const_cast<T&>(value));
      (*out_)[key] = nested;
    }
  }

 private:
  json* out_;
};

// Reads fields present in `in`; a key no field claims, or a value of the wrong
// JSON type, is an error naming the dotted path.
class Reader {
 public:
  Reader(const json& in, std::string path, std::string subject)
      : in_(in), path_(std::move(path)), subject_(std::move(subject)) {
    if (!in_.is_object()) Fail(path_.empty() ? "the document" : path_, "must be a JSON object");
  }
  template <class T>
  void operator()(const char* key, T& value) {
    seen_.insert(key);
    const auto it = in_.find(key);
    if (it == in_.end()) return;
    const std::string path = path_.empty() ? key : path_ + "." + key;
    const json& v = *it;
    if constexpr (std::is_same_v<T, bool>) {
      if (!v.is_boolean()) Fail(path, "must be true or false, got " + v.dump());
      value = v.get<bool>();
    } else if constexpr (std::is_integral_v<T>) {
      if (!v.is_number_integer()) Fail(path, "must be a whole number, got " + v.dump());
      if (std::is_unsigned_v<T> && v.get<std::int64_t>() < 0 && !v.is_number_unsigned())
        Fail(path, "must not be negative, got " + v.dump());
      const bool fits = v.is_number_unsigned()
                            ? v.get<std::uint64_t>() <= static_cast<std::uint64_t>(std::numeric_limits<T>::max())
                            : v.get<std::int64_t>() >= static_cast<std::int64_t>(std::numeric_limits<T>::min()) &&
                                  (std::is_unsigned_v<T> || v.get<std::int64_t>() <= static_cast<std::int64_t>(
                                                                                          std::numeric_limits<T>::max()));
      if (!fits) Fail(path, "is out of range, got " + v.dump());
      value = v.get<T>();
    } else if constexpr (std::is_floating_point_v<T>) {
      if (!v.is_number()) Fail(path, "must be a number, got " + v.dump());
      if (std::abs(v.get<double>()) > std::numeric_limits<T>::max()) Fail(path, "is out of range, got " + v.dump());
      value = v.get<T>();
    } else if constexpr (std::is_same_v<T, std::string>) {
      if (!v.is_string()) Fail(path, "must be a string, got " + v.dump());
      value = v.get<std::string>();
    } else if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
      if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
        Fail(path, "must be an array of 3 numbers, got " + v.dump());
      value = Eigen::Vector3d(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
    } else {
      Reader inner(v, path, subject_);
      Visit(inner, value);
      inner.RejectUnknown();
    }
  }
  void RejectUnknown(const std::set<std::string>& also_allowed = {}) const {
    for (const auto& [key, unused] : in_.items()) {
      if (!seen_.count(key) && !also_allowed.count(key))
        Fail(path_.empty() ? key : path_ + "." + key, "is not a known option");
    }
  }

 private:
  [[noreturn]] void Fail(const std::string& path, const std::string& what) const {
    throw Error("run options", subject_.empty() ? path : subject_ + ": " + path, what);
  }
  const json& in_;
  std::string path_, subject_;
  std::set<std::string> seen_;
};

template <class T>
json ToJson(const T& options) {
  json out = json::object();
  Writer w(&out);
  Visit(w, const_cast<T&>(options));
  return out;
}

json RunJson(const RunOptions& o) {
  json out = {{"schema", kSchema}};
  out.update(ToJson(o));
  return out;
}

void NeedOneOf(const std::string& value, std::initializer_list<const char*> allowed, const char* stage,
               const char* field) {
  std::string list;
  for (const char* a : allowed) {
    if (value == a) return;
    list += std::string(list.empty() ? "" : ", ") + a;
  }
  throw Error(stage, field, "'" + value + "' is not one of " + list);
}

// Runs a section's Check() and puts the section in front of the field.
template <class F>
void CheckSection(const char* section, F check) {
  try {
    check();
  } catch (const Error& e) {
    throw Error("run options", std::string(section) + "." + e.subject(), e.detail());
  }
}

}  // namespace

void TrainStageOptions::Check() const {
  optimizer.Check();
  optimizer.appearance.Check();
  optimizer.raster.Check();
  if (downscale < 1) throw Error("train", "downscale", "must be >= 1, got " + std::to_string(downscale));
  if (depth_prior != "surface" && depth_prior != "none" && depth_prior.rfind("cmd:", 0) != 0)
    throw Error("train", "depth_prior", "'" + depth_prior + "' is not one of surface, none, cmd:COMMAND");
  if (depth_prior == "cmd:") throw Error("train", "depth_prior", "'cmd:' names no command");
  NeedOneOf(appearance, {"auto", "on", "off"}, "train", "appearance");
  NeedOneOf(init_points, {"auto", "dense", "sparse"}, "train", "init_points");
  NeedOneOf(densify, {"auto", "on", "off"}, "train", "densify");
  if (!(init_max_scale_m >= 0)) throw Error("train", "init_max_scale_m", "must be >= 0 (0 = no cap), got " + FormatDouble(init_max_scale_m));
  if (init_pieces < 1) throw Error("train", "init_pieces", "must be >= 1, got " + std::to_string(init_pieces));
  if (!(init_spacing_m > 0)) throw Error("train", "init_spacing_m", "must be > 0, got " + FormatDouble(init_spacing_m));
  if (!(init_facade_step_m >= 0))
    throw Error("train", "init_facade_step_m", "must be >= 0, got " + FormatDouble(init_facade_step_m));
  if (!(anchor.filled_weight >= 0 && anchor.filled_weight <= 1))
    throw Error("train", "surface_filled_weight", "must be in [0, 1], got " + FormatDouble(anchor.filled_weight));
  if (!(anchor.step_weight >= 0 && anchor.step_weight <= 1))
    throw Error("train", "surface_step_weight", "must be in [0, 1], got " + FormatDouble(anchor.step_weight));
  if (!(anchor.step_reach_m >= 0))
    throw Error("train", "surface_step_reach_m", "must be >= 0, got " + FormatDouble(anchor.step_reach_m));
  if (!(anchor.step_min_m > 0))
    throw Error("train", "surface_step_min_m", "must be > 0, got " + FormatDouble(anchor.step_min_m));
}

void IduStageOptions::Check() const {
  NeedOneOf(mode, {"auto", "on", "off"}, "idu", "mode");
  if (refiner != "reproject" && (refiner.rfind("cmd:", 0) != 0 || refiner.size() == 4))
    throw Error("idu", "refiner", "'" + refiner + "' is not 'reproject' or 'cmd:COMMAND'");
  options.Check();
  reproject.Check();
  auto_decision.Check();
}

void MergeOptions::Check() const {
  stitch.Check();
  try {
    lod.Check();
  } catch (const Error& e) {
    throw Error("merge", "lod." + e.subject(), e.detail());
  }
  if (!(seam_gsd_m > 0)) throw Error("merge", "seam_gsd_m", "must be > 0, got " + FormatDouble(seam_gsd_m));
}

void DsmOptions::Check() const {
  NeedOneOf(source, {"reconstruction", "final"}, "dsm", "source");
  try {
    export_options.Check();
  } catch (const Error& e) {
    throw Error("dsm", "export." + e.subject(), e.detail());
  }
  try {
    compare.Check();
  } catch (const Error& e) {
    throw Error("dsm", "compare." + e.subject(), e.detail());
  }
}

void ExportOptions::Check() const {
  try {
    tiles3d_options.Check();
  } catch (const Error& e) {
    throw Error("exports", "tiles3d_options." + e.subject(), e.detail());
  }
}

void SlurmOptions::Check() const {
  if (cpus_per_task < 1) throw Error("slurm", "cpus_per_task", "must be >= 1, got " + std::to_string(cpus_per_task));
  if (mem_mb < 0) throw Error("slurm", "mem_mb", "must be >= 0 (0 = estimated), got " + std::to_string(mem_mb));
  if (!(poll_s > 0)) throw Error("slurm", "poll_s", "must be > 0, got " + FormatDouble(poll_s));
  // These go into job scripts: refuse what would break out of an #SBATCH line.
  for (const auto& [name, value] : {std::pair<const char*, const std::string&>{"partition", partition},
                                    {"account", account}, {"time_limit", time_limit}}) {
    if (value.find_first_of(" \t\n'\"$`;\\") != std::string::npos) {
      throw Error("slurm", name, "'" + value + "' holds a space, quote or shell character");
    }
  }
}

void ExecutorOptions::Check() const {
  NeedOneOf(kind, {"local", "inline", "slurm"}, "executor", "kind");
  if (jobs < 0) throw Error("executor", "jobs", "must be >= 0 (0 = automatic), got " + std::to_string(jobs));
  try {
    slurm.Check();
  } catch (const Error& e) {
    throw Error("executor", "slurm." + e.subject(), e.detail());
  }
}

void RunOptions::Check() const {
  CheckSection("ingest", [&] { ingest.Check(); });
  CheckSection("tiling", [&] { tiling.Check(); });
  CheckSection("sfm", [&] { sfm.Check(); });
  CheckSection("dense", [&] { dense.Check(); });
  CheckSection("train", [&] { train.Check(); });
  CheckSection("idu", [&] { idu.Check(); });
  CheckSection("merge", [&] { merge.Check(); });
  CheckSection("dsm", [&] { dsm.Check(); });
  CheckSection("exports", [&] { exports.Check(); });
  CheckSection("executor", [&] { executor.Check(); });
}

std::string RunOptionsToJson(const RunOptions& options) { return RunJson(options).dump(2) + "\n"; }

RunOptions RunOptionsFromJson(const std::string& text, const std::string& subject) {
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {
    throw Error("run options", subject, std::string("not valid JSON: ") + e.what());
  }
  if (!doc.is_object()) throw Error("run options", subject, "must be a JSON object");
  const auto found = doc.find("schema");
  if (found != doc.end() && !found->is_string()) {
    throw Error("run options", subject, "schema must be a string, got " + found->dump());
  }
  const std::string schema = found != doc.end() ? found->get<std::string>() : std::string(kSchema);
  if (schema != kSchema) throw Error("run options", subject, "schema is '" + schema + "', expected '" + kSchema + "'");
  RunOptions options;
  Reader reader(doc, "", subject);
  Visit(reader, options);
  reader.RejectUnknown({"schema"});
  return options;
}

void SetRunOption(RunOptions* options, const std::string& assignment) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw Error("run options", assignment, "expected SECTION.FIELD=VALUE, e.g. dense.sgm_p2=1.5");
  const std::string path = assignment.substr(0, eq), text = assignment.substr(eq + 1);
  json doc = RunJson(*options);
  json* node = &doc;
  std::size_t start = 0;
  while (true) {
    const std::size_t dot = path.find('.', start);
    const std::string key = path.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    if (!node->is_object() || !node->contains(key) || key == "schema")
      throw Error("run options", path, "is not a known option (see `skyfall run --print-config`)");
    node = &(*node)[key];
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  if (node->is_object()) throw Error("run options", path, "is a section; set one of its fields");
  json value = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded() || node->is_string()) value = text;  // strings need no quotes
  *node = value;
  *options = RunOptionsFromJson(doc.dump(), "--set " + path);
}

std::string TileOptionsJson(const RunOptions& o) {
  const json doc = {{"sfm", ToJson(o.sfm)}, {"dense", ToJson(o.dense)}, {"train", ToJson(o.train)}, {"idu", ToJson(o.idu)}};
  return doc.dump();
}

std::string DenseOptionsJson(const DenseOptions& options) { return ToJson(options).dump(); }

std::string IduEpisodesJson(const RunOptions& o) {
  json idu = ToJson(o.idu);
  idu.erase("mode");
  idu.erase("auto");
  return json({{"sfm", ToJson(o.sfm)}, {"dense", ToJson(o.dense)}, {"train", ToJson(o.train)}, {"idu", idu}}).dump();
}

std::string SfmOptionsJson(const SfmOptions& options) { return ToJson(options).dump(); }

}  // namespace skyfall
