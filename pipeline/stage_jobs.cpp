#include "pipeline/stage_jobs.h"


#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <cstdio>
#include <map>
#include <memory>
#include <sstream>
#include <nlohmann/json.hpp>

#include "catalogs/tile_catalog.h"
#include "core/atomic_file.h"
#include "core/ground_cell.h"
#include "core/error.h"
#include "core/sha256.h"
#include "core/simd.h"
#include "pipeline/city_entries.h"
#include "dense/dense_cells.h"
#include "sfm/export.h"
#include "dense/hole_fill.h"
#include "splat/dataset.h"
#include "splat/ply.h"
#include "ingest/radiometry.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

// Mean milliseconds per training step, by phase (trainer.h, StepProfile).
nlohmann::json StepMsJson(const StepProfile& p) {
  nlohmann::json j = {{"steps", p.steps}};
  for (const auto& [phase, ms] : p.MeanMsByPhase()) j[phase] = ms;
  return j;
}


// Per held-out view: its scores and the images written for it.
nlohmann::json HeldOutJson(const std::vector<HeldOutRender>& renders) {
  nlohmann::json views = nlohmann::json::array();
  for (const HeldOutRender& r : renders)
    views.push_back({{"name", r.name},
                     {"psnr_db", FiniteOrNull(r.psnr_db)},
                     {"fitted_psnr_db", FiniteOrNull(r.fitted_psnr_db)},
                     {"best_embedding_psnr_db", FiniteOrNull(r.best_embedding_psnr_db)},
                     {"best_embedding_view", r.best_embedding_view.empty() ? nlohmann::json() : nlohmann::json(r.best_embedding_view)},
                     {"images", {"heldout/" + r.name + "_render.png", "heldout/" + r.name + "_image.png",
                                 "heldout/" + r.name + "_error.png"}}});
  return views;
}

// A held-out view's render beside its image, and their difference (mean
// absolute difference over the channels, 0.25 of the unit range and more
// white), for a user to see where the model and the view disagree.
void WriteHeldOutImages(const std::vector<HeldOutRender>& renders, const fs::path& dir) {
  if (renders.empty()) return;
  fs::create_directories(dir);
  constexpr float kErrorFullScale = 0.25f;
  for (const HeldOutRender& r : renders) {
    const int w = r.width_px, h = r.height_px;
    WriteUnitPng((dir / (r.name + "_render.png")).string(), w, h, 3, r.rgb);
    WriteUnitPng((dir / (r.name + "_image.png")).string(), w, h, 3, r.target);
    std::vector<float> error(static_cast<std::size_t>(w) * h);
    for (std::size_t p = 0; p < error.size(); ++p) {
      float sum = 0;
      for (int c = 0; c < 3; ++c) sum += std::abs(r.rgb[3 * p + c] - r.target[3 * p + c]);
      error[p] = sum / (3.0f * kErrorFullScale);
    }
    WriteUnitPng((dir / (r.name + "_error.png")).string(), w, h, 1, error);
  }
}

// Each training view with cloud masked, as trained on: the image with its
// masked pixels tinted magenta, for a user to check what was left out.
void WriteCloudMasks(const std::vector<TrainView>& views, const std::vector<std::vector<std::uint8_t>>& cloudy,
                     const fs::path& dir) {
  fs::remove_all(dir);  // an earlier run's masks must not outlive this one's
  for (std::size_t j = 0; j < views.size(); ++j) {
    if (cloudy[j].empty() || std::find(cloudy[j].begin(), cloudy[j].end(), 1) == cloudy[j].end()) continue;
    fs::create_directories(dir);
    std::vector<float> rgb = views[j].rgb;
    constexpr float kTint[3] = {1.0f, 0.0f, 1.0f};
    for (std::size_t p = 0; p < cloudy[j].size(); ++p)
      if (cloudy[j][p])
        for (int c = 0; c < 3; ++c) rgb[3 * p + c] = 0.5f * rgb[3 * p + c] + 0.5f * kTint[c];
    const int w = static_cast<int>(views[j].camera.width_px), h = static_cast<int>(views[j].camera.height_px);
    WriteUnitPng((dir / (views[j].name + ".png")).string(), w, h, 3, rgb);
  }
}

// Centres closer than this are one point for any DSM or render at the
// product's 0.5 m cells: the report counts them (CoincidentGaussians).
constexpr double kCoincidentWithinM = 0.01;

std::string TrainReportJson(const TrainResult& r, const TrainOptions& o, int downscale, std::size_t views,
                            const std::string& appearance_reason) {
  nlohmann::json series = nlohmann::json::array();
  for (const TrainSample& s : r.series) {
    series.push_back({{"iteration", s.iteration},
                      {"elapsed_s", s.seconds},
                      {"loss", std::isfinite(s.loss) ? nlohmann::json(s.loss) : nlohmann::json()},
                      {"psnr_test_db", FiniteOrNull(s.psnr_test_db)},
                      {"gaussians", s.gaussians}});
  }
  const nlohmann::json doc = {
      {"status", ToString(r.report.status)},
      {"iterations", o.iterations},
      {"resumed_from_iteration", r.start_iteration},
      {"resolution_downscale", downscale},
      {"views", views},
      {"lambda_dssim", o.lambda_dssim},
      {"lambda_opacity", o.lambda_opacity},
      {"gaussians", r.cloud.size()},
      {"surface", r.surface ? nlohmann::json({{"iteration", r.surface_iteration}, {"gaussians", r.surface->size()}})
                            : nlohmann::json()},
      {"coincident_gaussians", {{"within_m", kCoincidentWithinM}, {"count", CoincidentGaussians(r.cloud, kCoincidentWithinM)}}},
      {"seconds_this_run", r.report.seconds},
      {"enabled", {{"entropy_opacity", o.lambda_opacity > 0},
                   {"densification", o.density.from_step <= o.density.until_step},
                   {"appearance_model", o.appearance.enabled},
                   {"pseudo_camera_depth", o.pseudo_interval > 0}}},
      {"appearance", {{"reason", appearance_reason},
                      {"model", o.appearance.enabled ? nlohmann::json(EnumName(o.appearance.model)) : nlohmann::json()},
                      {"fused_image", r.appearance_image.empty() ? nlohmann::json() : nlohmann::json(r.appearance_image)}}},
      {"held_out", HeldOutJson(r.held_out)},
      {"step_ms", StepMsJson(r.profile)},
      {"simd_path", SimdPathName(ActiveSimdPath())},
      {"series", series}};
  return doc.dump(2) + "\n";
}

// Decides whether the appearance model runs, and says why.
std::string ResolveAppearance(Switch mode, const std::vector<TrainView>& views, TrainOptions* o) {
  const int dates = DistinctAcquisitionDates(views);
  if (mode != Switch::kAuto) {
    o->appearance.enabled = mode == Switch::kOn;
    return std::string("--appearance ") + EnumName(mode);
  }
  o->appearance.enabled = dates >= 2;
  return "auto: training views from " + std::to_string(dates) + " acquisition date" + (dates == 1 ? "" : "s");
}

// A checkpoint is resumed only by a run whose settings its own still hold
// for (the same, or new options at their defaults: SettingsStillHold,
// `defaults` being the settings' JSON of default options); otherwise it is set
// aside (renamed, not deleted) and training starts again.
void SetAsideStaleCheckpoint(const fs::path& dir, const nlohmann::json& settings, const nlohmann::json& defaults,
                             Progress& progress) {
  const fs::path settings_path = dir / "settings.json";
  const fs::path checkpoint = dir / "checkpoint.bin";
  if (fs::exists(checkpoint)) {
    std::string previous;
    try {
      previous = ReadTextFile(settings_path.string());
    } catch (const std::exception&) {
    }
    if (!SettingsStillHold(previous, settings.dump(), defaults.dump())) {
      progress.Warn("splat train: " + checkpoint.string() +
                    " was written with other settings; moved to checkpoint.bin.stale, starting again");
      fs::rename(checkpoint, dir / "checkpoint.bin.stale");
    }
  }
  fs::create_directories(dir);
  WriteFileIfChanged(settings_path.string(), settings.dump(2) + "\n");
}


// The contents a training run starts from and holds to (tie points, dense
// heights, cameras): a checkpoint of other contents is not resumed.
nlohmann::json TrainInputsSha256(const std::string& sfm_dir, bool dense_start) {
  nlohmann::json out = nlohmann::json::object();
  std::vector<std::string> names = {"points.ply", "cameras.json"};
  if (dense_start) names.push_back("dense.ply");
  for (const std::string& name : names) {
    const fs::path path = fs::path(sfm_dir) / name;
    out[name] = fs::exists(path) ? nlohmann::json(Sha256FileHex(path.string())) : nlohmann::json(nullptr);
  }
  return out;
}

}  // namespace

std::vector<std::uint8_t> CellsNearSteps(const DenseCells& cells, double reach_m, double min_step_m) {
  std::vector<std::uint8_t> near(cells.points.size(), 0);
  if (cells.points.empty() || !(reach_m > 0)) return near;
  // The cells lie on a grid of cell_m: index them by their (column, row)
  // from the lowest corner, then look for a rise within the reach.
  Eigen::Vector2f lo = cells.points[0].head<2>();
  for (const Eigen::Vector3f& p : cells.points) lo = lo.cwiseMin(p.head<2>());
  std::vector<Eigen::Vector2i> at(cells.points.size());
  Eigen::Vector2i size(0, 0);
  for (std::size_t k = 0; k < at.size(); ++k) {
    const Eigen::Vector2f g = (cells.points[k].head<2>() - lo) / static_cast<float>(cells.cell_m);
    at[k] = Eigen::Vector2i(static_cast<int>(std::lround(g.x())), static_cast<int>(std::lround(g.y())));
    size = size.cwiseMax(at[k] + Eigen::Vector2i(1, 1));
  }
  std::vector<float> height(static_cast<std::size_t>(size.x()) * size.y(), std::numeric_limits<float>::quiet_NaN());
  for (std::size_t k = 0; k < at.size(); ++k)
    height[static_cast<std::size_t>(at[k].y()) * size.x() + at[k].x()] = cells.points[k].z();
  // The lowest and highest height within the reach (the highest as the
  // lowest of the negated heights), windows cut at the grid's edges.
  const int reach = std::max(1, static_cast<int>(std::lround(reach_m / cells.cell_m)));
  const std::vector<float> low = MinFilter(height, size.x(), size.y(), reach, WindowEdge::kClip);
  for (float& h : height) h = -h;
  const std::vector<float> minus_high = MinFilter(height, size.x(), size.y(), reach, WindowEdge::kClip);
  for (std::size_t k = 0; k < at.size(); ++k) {
    const std::size_t c = static_cast<std::size_t>(at[k].y()) * size.x() + at[k].x();
    near[k] = -minus_high[c] - low[c] > min_step_m;
  }
  return near;
}

std::vector<float> AnchorCellWeights(const DenseCells& cells, const AnchorWeightOptions& o) {
  const bool by_fill = o.filled_weight < 1.0, by_step = o.step_weight < 1.0 && o.step_reach_m > 0;
  if (!by_fill && !by_step) return {};  // all alike: no weights
  std::vector<float> w(cells.points.size(), 1.0f);
  if (by_fill)
    for (std::size_t k = 0; k < w.size(); ++k)
      if (cells.filled[k]) w[k] = static_cast<float>(o.filled_weight);
  if (!by_step) return w;
  const std::vector<std::uint8_t> near = CellsNearSteps(cells, o.step_reach_m, o.step_min_m);
  for (std::size_t k = 0; k < w.size(); ++k)
    if (near[k]) w[k] = std::min(w[k], static_cast<float>(o.step_weight));
  return w;
}


namespace {

nlohmann::json ExtentJson(const std::optional<GroundBox>& extent) {
  return extent ? BoxToJson(*extent) : nlohmann::json();
}

}  // namespace

bool DenseDone(const std::string& sfm_dir, const DenseOptions& options, const std::optional<GroundBox>& extent_enu_m) {
  const fs::path dir(sfm_dir);
  try {
    const nlohmann::json doc = nlohmann::json::parse(ReadTextFile((dir / "dense_report.json").string()));
    return doc.value("status", "") == "ok" && fs::exists(dir / "dense.ply") &&
           doc.value("extent_enu_m", nlohmann::json()) == ExtentJson(extent_enu_m) &&
           SettingsStillHold(doc.value("options", nlohmann::json()).dump(), DenseOptionsJson(options),
                             DenseOptionsJson(DenseOptions()));
  } catch (const std::exception&) {
    return false;
  }
}

DenseResult RunDenseJob(const DenseOptions& options, const std::string& sfm_dir, Progress& progress,
                        const std::optional<GroundBox>& extent_enu_m) {
  const fs::path dir(sfm_dir);
  const std::string report_path = (dir / "sfm_report.json").string();
  std::vector<DenseView> views;
  std::map<std::string, int> index;
  for (CameraEntry& entry : ReadCameraEntries((dir / "cameras.json").string())) {
    NormalizedImage pixels = ReadNormalizedImage(entry.source_image, entry.radiometry);
    if (pixels.width_px != entry.camera.width_px || pixels.height_px != entry.camera.height_px)
      throw Error("dense", entry.source_image, "size differs from cameras.json");
    // 8-bit scale for the cells' colours; NaN where there is no data, which
    // the sweep treats like a point outside the image.
    for (std::size_t k = 0; k < pixels.valid.size(); ++k)
      for (int c = 0; c < 3; ++c) pixels.rgb[3 * k + c] = pixels.valid[k] ? 255.0f * pixels.rgb[3 * k + c] : NAN;
    index[entry.name] = static_cast<int>(views.size());
    DenseView v;
    v.name = std::move(entry.name);
    v.camera = entry.camera;
    v.width_px = pixels.width_px;
    v.height_px = pixels.height_px;
    v.bands = 3;
    v.pixels = std::move(pixels.rgb);
    views.push_back(std::move(v));
  }
  nlohmann::json sfm_report;
  try {
    sfm_report = nlohmann::json::parse(ReadTextFile(report_path));
  } catch (const nlohmann::json::exception& e) {
    throw Error("dense", report_path, std::string("not valid JSON: ") + e.what());
  }
  std::vector<DensePair> pairs;
  for (const nlohmann::json& p : sfm_report.value("pairs", nlohmann::json::array())) {
    const auto a = index.find(p.value("a", std::string())), b = index.find(p.value("b", std::string()));
    if (a != index.end() && b != index.end()) pairs.push_back({a->second, b->second, p.value("verified", 0)});
  }
  std::vector<Eigen::Vector3f> points_f, colours;
  ReadSfmPoints((dir / "points.ply").string(), &points_f, &colours);
  std::vector<Eigen::Vector3d> points;
  for (const auto& p : points_f) points.push_back(p.cast<double>());

  DenseResult r = RunDenseHeights(options, views, pairs, points, progress, extent_enu_m);
  if (r.report.status == StageStatus::kOk) WriteFileAtomic((dir / "dense.ply").string(), DenseCellsPly(r.grid));
  else fs::remove(dir / "dense.ply");  // an earlier run's heights must not outlive a failed rerun
  nlohmann::json used = nlohmann::json::array();
  for (const DensePair& p : r.pairs_used) used.push_back({{"a", views[p.a].name}, {"b", views[p.b].name}, {"verified", p.verified}});
  const nlohmann::json doc = {{"status", ToString(r.report.status)}, {"message", r.report.message},
                              {"seconds", r.report.seconds},      {"metrics", r.report.metrics},
                              {"cell_m", r.grid.cell_m},          {"extent_enu_m", ExtentJson(extent_enu_m)},
                              {"options", nlohmann::json::parse(DenseOptionsJson(options))}, {"pairs", used}};
  WriteFileAtomic((dir / "dense_report.json").string(), doc.dump(2) + "\n");
  return r;
}

SfmResult RunSfmJob(const SfmOptions& options, const AoiCatalog& catalog, const std::string& out_dir,
                    bool colmap_images, Progress& progress) {
  SfmResult r = RunSfm(options, catalog, progress);
  WriteSfmOutputs(r, catalog, out_dir, colmap_images);
  return r;
}

InitSpacing InitSpacingM(const TrainStageOptions& stage, const DenseCells& dense) {
  if (stage.init_spacing_m > 0) return {stage.init_spacing_m, "train.init_spacing_m"};
  return {InitSpacingForDenseCellM(dense.cell_m),
          fmt::format("automatic: two dense cells of {:.2f} m, at least {:.1f} m", dense.cell_m, kMinInitSpacingM)};
}

void MaskViews(const TrainStageOptions& stage, const DenseCells& dense, const RasterOptions& raster,
               std::vector<TrainView>* views, TrainDecisions* decided,
               std::vector<std::vector<std::uint8_t>>* cloudy) {
  if (cloudy) cloudy->assign(views->size(), {});
  const int training_views =
      static_cast<int>(std::count_if(views->begin(), views->end(), [](const TrainView& v) { return !v.held_out; }));
  const int needed = stage.cloud_mask.min_other_views + 1;
  decided->cloud_mask = false;
  decided->cloud_mask_why = !stage.cloud_mask.enabled ? "train.cloud_mask.enabled is false (the default, D-137)"
                            : dense.points.empty()    ? "no dense heights to give each pixel its ground point"
                            : training_views < needed
                                ? fmt::format("{} training views, fewer than {}: too few others to compare with",
                                              training_views, needed)
                                : "";
  const bool clouds = decided->cloud_mask_why.empty();
  if (dense.points.empty() || (!stage.mask_beyond_reconstruction && !clouds)) return;
  const std::vector<RenderOutput<float>> covers =
      RenderDenseCover(dense, InitSpacingM(stage, dense).value_m, raster, *views);
  if (stage.mask_beyond_reconstruction) decided->masked_beyond_fraction = MaskBeyondReconstruction(covers, views);
  if (!clouds) return;
  std::vector<std::vector<std::uint8_t>> before;
  for (const TrainView& v : *views) before.push_back(v.valid);
  const std::vector<double> fractions = MaskClouds(dense, covers, stage.cloud_mask, views);
  if (cloudy) {
    for (std::size_t j = 0; j < views->size(); ++j) {
      const std::vector<std::uint8_t>& after = (*views)[j].valid;
      if (after.empty()) continue;
      (*cloudy)[j].assign(after.size(), 0);
      for (std::size_t p = 0; p < after.size(); ++p)
        (*cloudy)[j][p] = !after[p] && (before[j].empty() || before[j][p]);
    }
  }
  decided->cloud_mask = true;
  decided->cloud_mask_why = fmt::format(
      "dense start, {} training views: pixels far brighter and whiter than the other views at their ground point "
      "are not trained on; held-out views are scored as given",
      training_views);
  decided->cloud_masked_fraction.clear();
  for (std::size_t j = 0; j < views->size(); ++j)
    if (!(*views)[j].held_out) decided->cloud_masked_fraction.emplace_back((*views)[j].name, fractions[j]);
}

TrainDownscale ResolveTrainDownscale(int asked, const std::string& sfm_dir) {
  if (asked > 0) return {asked, 0.0, "train.downscale " + std::to_string(asked)};
  // The GSD at the frame origin (in the AOI): a satellite is hundreds of
  // kilometres away, so the tile's place in the AOI does not change it.
  double finest_m = std::numeric_limits<double>::infinity();
  for (const CameraEntry& e : ReadCameraEntries((fs::path(sfm_dir) / "cameras.json").string()))
    finest_m = std::min(finest_m, e.camera.PixelFootprintM(Eigen::Vector3d::Zero()));
  const int factor = TrainDownscaleForGsdM(finest_m);
  const double gsd_m = std::isfinite(finest_m) ? finest_m : 0.0;
  return {factor, gsd_m,
          fmt::format("automatic: finest GSD {:.2f} m, {} {} m", gsd_m, factor == 1 ? "at least" : "under",
                      kTrainAtFullResolutionGsdM)};
}

TrainJobResult RunTrainJob(const TrainStageOptions& stage, const std::string& sfm_dir, const std::string& out_dir,
                           Progress& progress) {
  stage.Check();
  TrainOptions options = stage.optimizer;
  TrainJobResult result;
  TrainDecisions& decided = result.decisions;
  std::vector<Eigen::Vector3f> points, colours;
  ReadSfmPoints((fs::path(sfm_dir) / "points.ply").string(), &points, &colours);
  const fs::path dense_path = fs::path(sfm_dir) / "dense.ply";
  if (stage.init_points == InitPoints::kDense && !fs::exists(dense_path))
    throw Error("splat", dense_path.string(), "missing: run `skyfall dense --sfm " + sfm_dir +
                                                  "` first, or train with --init-points sparse");
  decided.dense_start =
      stage.init_points == InitPoints::kDense || (stage.init_points == InitPoints::kAuto && fs::exists(dense_path));
  const std::size_t tie_points = points.size();
  std::unique_ptr<SurfaceDepthPrior> surface;  // the dense heights, to anchor training to
  DenseCells dense;
  if (decided.dense_start) {
    dense = ReadDenseCells(dense_path.string());
    if (options.surface.lambda_depth > 0 || options.surface.lambda_alpha > 0)
      surface = std::make_unique<SurfaceDepthPrior>(dense.points, dense.cell_m,
                                                    AnchorCellWeights(dense, stage.anchor));
    // Beside a step the dense grid's own cells start Gaussians of its own
    // size, so a roof's edge is not drawn with init_spacing_m blobs.
    const std::vector<std::uint8_t> fine = CellsNearSteps(dense, stage.init_step_reach_m, stage.init_step_min_m);
    decided.init_fine_points = static_cast<std::size_t>(std::count(fine.begin(), fine.end(), 1));
    decided.init_spacing = InitSpacingM(stage, dense);
    ThinToGrid(decided.init_spacing.value_m, dense.points, dense.colours, points, colours, &points, &colours, &fine);
  }
  decided.surface_anchor = surface != nullptr;
  decided.densify = stage.densify == Switch::kOn || (stage.densify == Switch::kAuto && !decided.dense_start);
  if (!decided.densify) options.density.from_step = options.iterations + 1;  // never reached
  decided.downscale = ResolveTrainDownscale(stage.downscale, sfm_dir);
  std::vector<TrainView> views = LoadTrainViews(sfm_dir, decided.downscale.factor);
  std::vector<std::vector<std::uint8_t>> cloudy;
  MaskViews(stage, dense, options.raster, &views, &decided, &cloudy);
  WriteCloudMasks(views, cloudy, fs::path(out_dir) / "cloud_masks");
  if (decided.cloud_mask) {
    int with_cloud = 0;
    for (const auto& [name, fraction] : decided.cloud_masked_fraction) with_cloud += fraction > 0;
    progress.Info(fmt::format("splat train: cloud mask: {} of {} training views hold cloud", with_cloud,
                              decided.cloud_masked_fraction.size()));
  }
  progress.Info(fmt::format(
      "splat train: {} views ({} held out) at 1/{} resolution ({}), {} initial points ({}), {} iterations, "
      "densification {}",
      views.size(),
      std::count_if(views.begin(), views.end(), [](const TrainView& v) { return v.held_out; }),
      decided.downscale.factor, decided.downscale.why, points.size(),
      decided.dense_start ? fmt::format("dense heights thinned to {} m ({} cells beside steps kept), and tie points in "
                                        "their holes", decided.init_spacing.value_m, decided.init_fine_points)
                          : fmt::format("{} tie points", tie_points),
      options.iterations, decided.densify ? "on" : "off"));
  std::unique_ptr<DepthPrior> depth_prior;
  if (stage.depth_prior == "surface") {
    depth_prior =
        std::make_unique<SurfaceDepthPrior>(points, decided.dense_start ? 2.0 * decided.init_spacing.value_m : 2.0);
  } else if (stage.depth_prior.rfind("cmd:", 0) == 0) {
    fs::create_directories(fs::path(out_dir) / "pseudo");
    depth_prior = std::make_unique<CommandDepthPrior>(stage.depth_prior.substr(4), (fs::path(out_dir) / "pseudo").string());
  }
  if (!depth_prior) options.pseudo_interval = 0;
  decided.appearance_reason = ResolveAppearance(stage.appearance, views, &options);
  decided.appearance = options.appearance.enabled;
  progress.Info(fmt::format("splat train: appearance model {} ({})", decided.appearance ? "on" : "off",
                            decided.appearance_reason));
  const fs::path checkpoints = fs::path(out_dir) / "checkpoints";
  // Every option is in the stamp's "options"; beside it, what was decided
  // from the options and the inputs.
  SetAsideStaleCheckpoint(checkpoints,
                          {{"options", nlohmann::json::parse(TrainCheckpointJson(stage))},
                           {"inputs", TrainInputsSha256(sfm_dir, decided.dense_start)},
                           {"appearance_model", options.appearance.enabled},
                           {"init_points", decided.dense_start ? "dense" : "sparse"},
                           {"densify", decided.densify},
                           {"surface_anchor", decided.surface_anchor}},
                          {{"options", nlohmann::json::parse(TrainCheckpointJson(TrainStageOptions()))}}, progress);
  // A dense start capped below its spacing would leave gaps between its Gaussians.
  const double init_cap_m =
      stage.init_max_scale_m <= 0 ? std::numeric_limits<double>::infinity()
      : decided.dense_start       ? std::max(stage.init_max_scale_m, decided.init_spacing.value_m)
                                  : stage.init_max_scale_m;
  GaussianCloud init = InitializeFromPoints(points, colours, init_cap_m, decided.dense_start ? 1 : stage.init_pieces);
  result.train = TrainGaussians(options, std::move(init), views, checkpoints.string(), progress, depth_prior.get(),
                                surface.get());
  WriteGaussiansPly((fs::path(out_dir) / "scene.ply").string(), result.train.cloud);
  const fs::path surface_ply = fs::path(out_dir) / "surface.ply";  // TileSurfacePath
  if (result.train.surface) WriteGaussiansPly(surface_ply.string(), *result.train.surface);
  else fs::remove(surface_ply);  // an earlier run's must not outlive this one's scene
  WriteHeldOutImages(result.train.held_out, fs::path(out_dir) / "heldout");
  for (HeldOutRender& r : result.train.held_out) {  // written: the tile's later stages need only the scores
    std::vector<float>().swap(r.rgb);
    std::vector<float>().swap(r.target);
  }
  WriteFileAtomic((fs::path(out_dir) / "train_report.json").string(),
                  TrainReportJson(result.train, options, decided.downscale.factor, views.size(), decided.appearance_reason));
  return result;
}

IduJobResult RunIduJob(const IduStageOptions& options, const TrainStageOptions& train, const std::string& sfm_dir,
                       const std::string& scene_ply, const GroundBox& core, const std::string& out_dir,
                       const std::string& episodes_stamp, Progress& progress) {
  options.Check();
  IduJobResult result;
  const fs::path dense_path = fs::path(sfm_dir) / "dense.ply";
  DenseCells dense;
  if (fs::exists(dense_path)) dense = ReadDenseCells(dense_path.string());
  result.decision = DecideIdu(options.mode, options.auto_decision, dense.points, dense.filled, dense.cell_m);
  progress.Info("idu: " + std::string(result.decision.on ? "on" : "off") + " (" + result.decision.why + ")");
  const fs::path scene_out = fs::path(out_dir) / "scene.ply";
  if (!result.decision.on) {
    fs::remove(scene_out);
    fs::remove(fs::path(out_dir) / "idu_report.json");
    return result;
  }
  std::vector<TrainView> views = LoadTrainViews(sfm_dir, ResolveTrainDownscale(train.downscale, sfm_dir).factor);
  TrainDecisions as_trained;  // the reconstruction's masks, as it was trained and scored
  MaskViews(train, dense, train.optimizer.raster, &views, &as_trained);
  const GaussianCloud scene = ReadGaussiansPly(scene_ply);
  std::vector<TrainView> satellite_train;
  for (const TrainView& v : views)
    if (!v.held_out) satellite_train.push_back(v);
  satellite_train = MatchSceneAppearance(scene, std::move(satellite_train), train.optimizer.raster);
  std::vector<TrainView> idu_views = satellite_train;  // held-out views keep their own colours: they measure
  for (const TrainView& v : views)
    if (v.held_out) idu_views.push_back(v);
  std::unique_ptr<SurfaceDepthPrior> surface;
  if (!dense.points.empty())
    surface = std::make_unique<SurfaceDepthPrior>(dense.points, dense.cell_m,
                                                  AnchorCellWeights(dense, train.anchor));
  auto height = [&](double e, double n) { return surface ? surface->HeightAt(e, n) : NAN; };
  const std::unique_ptr<Refiner> refiner =
      MakeRefiner(options.refiner, satellite_train, options.reproject, (fs::path(out_dir) / "refiner").string(),
                  "idu.refiner", options.options.geometry == IduGeometry::kSurface ? surface.get() : nullptr);
  fs::remove(scene_out);  // until this run has finished
  result.idu = RunIdu(options.options, train.optimizer, scene, idu_views, core,
                      ReadCamerasFrameOrigin((fs::path(sfm_dir) / "cameras.json").string()), height, surface.get(), *refiner,
                      out_dir, episodes_stamp, progress);
  WriteGaussiansPly(scene_out.string(), result.idu.cloud);
  const nlohmann::json doc = {{"status", "ok"}, {"refiner", options.refiner}, {"seconds", result.idu.report.seconds},
                              {"decision", {{"on", true}, {"why", result.decision.why},
                                            {"facade_ratio", result.decision.facade_ratio},
                                            {"measured_fraction", result.decision.measured_fraction}}},
                              {"episodes", nlohmann::json::parse(IduEpisodesJson(result.idu.episodes))}};
  WriteFileAtomic((fs::path(out_dir) / "idu_report.json").string(), doc.dump(2) + "\n");
  return result;
}

void RenderSceneJob(const std::string& scene_ply, const std::string& cameras_json, const std::string& out_dir,
                    int downscale, Progress& progress) {
  const GaussianCloud cloud = ReadGaussiansPly(scene_ply);
  const auto cameras = ReadCameras(cameras_json);
  progress.Begin("splat render", cameras.size());
  std::size_t done = 0;
  for (const auto& [name, full] : cameras) {
    const RenderOutput<float> r = RenderGaussians(cloud, DownscaledCamera(full, downscale), RasterOptions{});
    const int w = r.width_px, h = r.height_px;
    std::vector<std::uint8_t> grey(static_cast<size_t>(w) * h);
    // Depth: absolute camera depth as float, and a min-max visualization.
    std::vector<float> depth(r.depth.size());
    float lo = 1e30f, hi = -1e30f;
    for (size_t k = 0; k < depth.size(); ++k) {
      if (r.alpha[k] < 0.5f) continue;
      lo = std::min(lo, r.depth[k]);
      hi = std::max(hi, r.depth[k]);
    }
    for (size_t k = 0; k < depth.size(); ++k) {
      depth[k] = r.alpha[k] >= 0.5f ? static_cast<float>(r.depth[k] + r.reference_depth_m) : NAN;
      grey[k] = r.alpha[k] >= 0.5f && hi > lo ? static_cast<std::uint8_t>(255.0f * (hi - r.depth[k]) / (hi - lo)) : 0;
    }
    WriteUnitPng((fs::path(out_dir) / (name + "_rgb.png")).string(), w, h, 3, r.rgb);
    WriteBytePng((fs::path(out_dir) / (name + "_depth.png")).string(), w, h, 1, grey.data());
    WriteFloatTiff((fs::path(out_dir) / (name + "_depth.tif")).string(), w, h, depth.data());
    progress.Advance(++done, name);
  }
  progress.End();
}

}  // namespace skyfall
