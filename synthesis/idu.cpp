#include "synthesis/idu.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <unordered_set>
#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "splat/losses.h"
#include "splat/ply.h"
#include "splat/rasterizer.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

fs::path EpisodeDir(const std::string& out_dir, int episode) {
  return fs::path(out_dir) / ("episode_" + std::to_string(episode));
}

// Keeps finished episodes only when they were made with the same options.
void ForgetOtherRuns(const std::string& out_dir, const std::string& options_json, Progress& progress) {
  const fs::path stamp = fs::path(out_dir) / "idu_options.json";
  std::string old;
  if (fs::exists(stamp)) old = ReadTextFile(stamp.string());
  if (old == options_json) return;
  bool removed = false;
  if (fs::exists(out_dir)) {
    for (const auto& entry : fs::directory_iterator(out_dir)) {
      if (entry.path().filename().string().rfind("episode_", 0) == 0) {
        fs::remove_all(entry.path());
        removed = true;
      }
    }
  }
  if (removed) progress.Info("idu: options changed since the last run; its episodes are discarded");
  fs::create_directories(out_dir);
  WriteFileAtomic(stamp.string(), options_json);
}

// What an episode trains on from one orbit view: the render's surface
// depth (absolute, for the refiner) and the depth target (relative, for the
// Pearson loss), both NaN where the render is not opaque.
struct OrbitRender {
  RefineInput input;
  std::vector<float> depth_target;
  std::vector<std::uint8_t> valid;
  std::vector<std::uint8_t> hole;  // surface where the render is transparent (PlaceOnSurface with fill_holes)
};

OrbitRender RenderOrbitView(const GaussianCloud& cloud, const OrbitView& view, RasterOptions raster) {
  raster.median_depth = true;
  const RenderOutput<float> r = RenderGaussians(cloud, view.camera, raster);
  OrbitRender out;
  out.input.name = view.name;
  out.input.camera = view.camera;
  out.input.rgb = r.rgb;
  out.input.elevation_deg = view.elevation_deg;
  out.input.azimuth_deg = view.azimuth_deg;
  const std::size_t n = r.alpha.size();
  out.input.depth_m.assign(n, NAN);
  out.depth_target.assign(n, NAN);
  out.valid.assign(n, 0);
  for (std::size_t k = 0; k < n; ++k) {
    if (r.alpha[k] < 0.5f) continue;
    const float relative = std::isfinite(r.median_depth[k]) ? r.median_depth[k] : r.depth[k];
    out.input.depth_m[k] = static_cast<float>(relative + r.reference_depth_m);
    out.depth_target[k] = r.depth[k];
    out.valid[k] = 1;
  }
  return out;
}

// Geometry "surface": where the render is opaque and the height field has an
// answer, the orbit pixel lies on the height field (its steps are the walls
// the Gaussians lack) for the refiner and for the depth target alike.
// With `fill_holes`, also where the render is transparent: those pixels
// become valid and are marked as holes.
void PlaceOnSurface(const SurfaceDepthPrior& surface, bool fill_holes, OrbitRender* render) {
  const PinholeCamera& cam = render->input.camera;
  const double reference_m = cam.cam_from_world_translation.z();  // the render's reference depth
  const DepthMap m = surface.DepthRelativeTo(cam, reference_m);
  render->hole.assign(m.depth.size(), 0);
  for (std::size_t p = 0; p < m.depth.size(); ++p) {
    if (!m.valid[p]) continue;
    if (!render->valid[p]) {
      if (!fill_holes) continue;
      render->valid[p] = 1;
      render->hole[p] = 1;
    }
    render->depth_target[p] = m.depth[p];
    render->input.depth_m[p] = static_cast<float>(m.depth[p] + reference_m);
  }
}

// The surface normal at pixel (x, y) of a depth map, whose back-projected
// point is `centre`, from the back-projected neighbours: along each image
// axis the neighbour nearer in depth, so that a pixel next to a depth step
// takes the tangent of its own face. Zero where a neighbour pair is missing.
Eigen::Vector3d SurfaceNormal(const PixelToWorld& to_world, const std::vector<float>& depth_m, int W, int H, int x,
                              int y, const Eigen::Vector3d& centre) {
  auto point = [&](int u, int v, Eigen::Vector3d* X) {
    if (u < 0 || v < 0 || u >= W || v >= H) return false;
    const float d = depth_m[static_cast<std::size_t>(v) * W + u];
    if (!std::isfinite(d)) return false;
    *X = to_world(u, v, d);
    return true;
  };
  if (!centre.allFinite()) return Eigen::Vector3d::Zero();
  auto tangent = [&](int dx, int dy, Eigen::Vector3d* t) {
    Eigen::Vector3d a, b;
    const bool has_a = point(x + dx, y + dy, &a), has_b = point(x - dx, y - dy, &b);
    if (!has_a && !has_b) return false;
    if (has_a && (!has_b || (a - centre).squaredNorm() <= (b - centre).squaredNorm())) *t = a - centre;
    else *t = centre - b;
    return true;
  };
  Eigen::Vector3d tu, tv;
  if (!tangent(1, 0, &tu) || !tangent(0, 1, &tv)) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d n = tu.cross(tv);
  return n.norm() > 0 ? n.normalized() : Eigen::Vector3d::Zero();
}

// One Gaussian per `voxel_m` cube at the hole pixels' surface points, of the
// refined colour there (the first such pixel of a cube), opacity 0.5: enough
// for the photometric loss to shape it from the first step. It is a disc in
// the surface's plane (standard deviation half the cube across, a tenth of
// that along the normal): a ball on a wall would reach half a cube out over
// the ground beside it and raise the nadir DSM there.
GaussianCloud HoleGaussians(const std::vector<OrbitRender>& renders, const std::vector<RefinedSamples>& refined,
                            double voxel_m) {
  constexpr double kThicknessRatio = 0.1;  // normal / in-plane standard deviation
  GaussianCloud out;
  std::unordered_set<std::uint64_t> taken;
  auto key = [&](const Eigen::Vector3d& x) {
    auto q = [&](double v) { return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(v / voxel_m)) & 0x1FFFFF); };
    return q(x.x()) | (q(x.y()) << 21) | (q(x.z()) << 42);
  };
  const float log_across = static_cast<float>(std::log(0.5 * voxel_m));
  const float log_along_normal = static_cast<float>(std::log(0.5 * voxel_m * kThicknessRatio));
  for (std::size_t v = 0; v < renders.size(); ++v) {
    const OrbitRender& r = renders[v];
    const PinholeCamera& cam = r.input.camera;
    const PixelToWorld to_world(cam);
    for (std::size_t p = 0; p < r.hole.size(); ++p) {
      if (!r.hole[p]) continue;
      const int x = static_cast<int>(p % cam.width_px), y = static_cast<int>(p / cam.width_px);
      const Eigen::Vector3d X = to_world(x, y, r.input.depth_m[p]);
      if (!taken.insert(key(X)).second) continue;
      const Eigen::Vector3d normal = SurfaceNormal(to_world, r.input.depth_m, cam.width_px, cam.height_px, x, y, X);
      const std::size_t k = out.size();
      out.resize(k + 1);
      out.means[k] = X.cast<float>();
      out.log_scales[k].setConstant(log_across);
      out.rotations[k] = Eigen::Vector4f(1, 0, 0, 0);
      if (normal.squaredNorm() > 0) {  // local z along the normal
        const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), normal);
        out.rotations[k] = Eigen::Vector4f(q.w(), q.x(), q.y(), q.z());
        out.log_scales[k].z() = log_along_normal;
      }
      out.opacity_logits[k] = 0.0f;  // sigmoid(0) = 0.5
      out.sh[k].fill(0.0f);
      for (int c = 0; c < 3; ++c)
        out.sh[k][c * kShCoeffsPerChannel] = static_cast<float>(ShDcFromColour(refined[v][0][3 * p + c]));
    }
  }
  return out;
}

// One PNG per view (`image(v)`: its RGB in [0, 1]) in `dir`, written in
// parallel with fast compression: working images, hundreds per run.
template <class Image>
void WriteViewPngs(const fs::path& dir, const std::vector<OrbitView>& views, Image image) {
  tbb::parallel_for(std::size_t{0}, views.size(), [&](std::size_t v) {
    WriteUnitPng((dir / (views[v].name + ".png")).string(), views[v].camera.width_px, views[v].camera.height_px, 3,
                 image(v), PngCompression::kFast);
  });
}

double MedianHeight(const GaussianCloud& cloud) {
  if (cloud.size() == 0) return 0.0;
  std::vector<float> z;
  for (const auto& p : cloud.means) z.push_back(p.z());
  std::nth_element(z.begin(), z.begin() + z.size() / 2, z.end());
  return z[z.size() / 2];
}

TrainOptions EpisodeTrainOptions(const IduOptions& o, TrainOptions t, int episode) {
  t.iterations = o.iterations_per_episode;
  t.seed = o.seed + 7919ull * static_cast<std::uint64_t>(episode + 1);
  t.lambda_opacity = o.lambda_opacity;  // the paper turns opacity regularization off for IDU
  t.opacity_reg_from = 0;               // the scene is trained: no warm-up
  t.appearance.enabled = false;      // one fixed appearance: the reconstruction's fused cloud
  t.appearance_image.clear();
  t.pseudo_interval = 0;             // the refined views' depth loss takes the pseudo views' place
  t.synthetic_fraction = o.synthetic_fraction;
  t.lambda_view_depth = o.lambda_depth;
  t.keep_snapshots = false;
  t.lr.scale_late = 0;               // episodes keep lr_scale, as measured (D-130)
  t.surface_at = 0;                  // the DSMs' surface is the reconstruction's
  t.eval_interval = std::max(1, o.iterations_per_episode);
  t.checkpoint_interval = std::max(1, o.iterations_per_episode);
  if (o.densify) {
    t.density.interval_steps = std::max(1, o.densify_interval);
    t.density.from_step = std::max(1, static_cast<int>(o.densify_from_fraction * o.iterations_per_episode));
    t.density.until_step = static_cast<int>(o.densify_until_fraction * o.iterations_per_episode);
  } else {
    t.density.from_step = o.iterations_per_episode + 1;
  }
  return t;
}

json EpisodeJson(const IduEpisode& e) {
  json step_ms = json::object();
  for (const auto& [phase, ms] : e.step_ms) step_ms[phase] = ms;
  return {{"episode", e.episode},         {"elevation_deg", e.elevation_deg},   {"radius_m", e.radius_m},
          {"views", e.views},             {"render_seconds", e.render_seconds}, {"refine_seconds", e.refine_seconds},
          {"train_seconds", e.train_seconds}, {"refined_coverage", e.refined_coverage},
          {"psnr_test_start_db", std::isfinite(e.psnr_test_start_db) ? json(e.psnr_test_start_db) : json(nullptr)},
          {"psnr_test_db", std::isfinite(e.psnr_test_db) ? json(e.psnr_test_db) : json(nullptr)},
          {"gaussians", e.gaussians},     {"hole_gaussians", e.hole_gaussians}, {"step_ms", step_ms},  {"reused", e.reused}};
}

IduEpisode EpisodeFromJson(const json& j) {
  IduEpisode e;
  e.episode = j.at("episode");
  e.elevation_deg = j.at("elevation_deg");
  e.radius_m = j.at("radius_m");
  e.views = j.at("views");
  e.render_seconds = j.at("render_seconds");
  e.refine_seconds = j.at("refine_seconds");
  e.train_seconds = j.at("train_seconds");
  e.refined_coverage = j.at("refined_coverage");
  e.psnr_test_start_db = j.at("psnr_test_start_db").is_null() ? NAN : j.at("psnr_test_start_db").get<double>();
  e.psnr_test_db = j.at("psnr_test_db").is_null() ? NAN : j.at("psnr_test_db").get<double>();
  e.gaussians = j.at("gaussians");
  e.hole_gaussians = j.value("hole_gaussians", std::size_t{0});
  if (j.contains("step_ms"))
    for (const auto& [phase, ms] : j.at("step_ms").items()) e.step_ms.emplace_back(phase, ms.get<double>());
  e.reused = true;
  return e;
}

// The episodes an earlier run finished, in order, stopping at the first gap.
std::vector<IduEpisode> FinishedEpisodes(const std::string& out_dir, int episodes) {
  std::vector<IduEpisode> done;
  for (int k = 0; k < episodes; ++k) {
    const fs::path marker = EpisodeDir(out_dir, k) / "episode.json";
    if (!fs::exists(marker) || !fs::exists(EpisodeDir(out_dir, k) / "scene.ply")) break;
    try {
      done.push_back(EpisodeFromJson(json::parse(ReadTextFile(marker.string()))));
    } catch (const std::exception&) {
      break;  // unreadable: redo from here
    }
  }
  return done;
}

}  // namespace

std::string IduEpisodesJson(const std::vector<IduEpisode>& episodes) {
  json list = json::array();
  for (const IduEpisode& e : episodes) list.push_back(EpisodeJson(e));
  return list.dump();
}

void IduOptions::Check() const {
  CheckOptionRanges(*this, "idu");  // the orbit's ranges too, as idu.orbit.*
}

namespace {

// Every orbit view of an episode rendered from the scene as the episode
// starts (placed on the height field with geometry 'surface'), their PNGs
// under dir/renders, and the share of their pixels the scene covers.
std::vector<OrbitRender> RenderEpisodeViews(const IduOptions& o, const RasterOptions& raster,
                                            const GaussianCloud& cloud, const std::vector<OrbitView>& views,
                                            const SurfaceDepthPrior* surface, const fs::path& dir,
                                            std::vector<RefineInput>* inputs, IduEpisode* ep) {
  Stopwatch phase;
  std::vector<OrbitRender> renders;
  std::size_t opaque = 0, pixels = 0;
  for (const OrbitView& v : views) {
    renders.push_back(RenderOrbitView(cloud, v, raster));
    if (surface && o.geometry == IduGeometry::kSurface) PlaceOnSurface(*surface, o.fill_holes, &renders.back());
    inputs->push_back(renders.back().input);
    for (std::uint8_t m : renders.back().valid) opaque += m;
    pixels += renders.back().valid.size();
  }
  WriteViewPngs(dir / "renders", views, [&](std::size_t v) -> const std::vector<float>& { return (*inputs)[v].rgb; });
  ep->refined_coverage = pixels ? static_cast<double>(opaque) / pixels : 0.0;
  ep->render_seconds = phase.Seconds();
  return renders;
}

// The refined orbit views as synthetic training views: the first sample as
// the target, the others as further targets, the render's mask and depth.
void AppendRefinedViews(const std::vector<OrbitView>& views, const std::vector<OrbitRender>& renders,
                        const std::vector<RefinedSamples>& refined, int samples, std::vector<TrainView>* mixed) {
  for (std::size_t v = 0; v < views.size(); ++v) {
    if (static_cast<int>(refined[v].size()) != samples)
      throw Error("idu", views[v].name, "the refiner returned " + std::to_string(refined[v].size()) + " samples, not " +
                                            std::to_string(samples));
    TrainView t;
    t.name = views[v].name;
    t.camera = views[v].camera;
    t.synthetic = true;
    t.rgb = refined[v][0];
    t.extra_rgb.assign(refined[v].begin() + 1, refined[v].end());
    t.valid = renders[v].valid;
    t.depth_target = renders[v].depth_target;
    mixed->push_back(std::move(t));
  }
}

}  // namespace

IduResult RunIdu(const IduOptions& o, const TrainOptions& train, GaussianCloud cloud,
                 const std::vector<TrainView>& satellite, const GroundBox& core, const GeodeticPoint& enu_origin,
                 const std::function<double(double, double)>& surface_height_m, const SurfaceDepthPrior* surface,
                 Refiner& refiner, const std::string& out_dir, const std::string& options_json, Progress& progress) {
  o.Check();
  Stopwatch clock;
  IduResult result;
  result.report.stage = "idu";
  ForgetOtherRuns(out_dir, options_json, progress);
  result.episodes = FinishedEpisodes(out_dir, o.orbit.episodes);
  if (!result.episodes.empty()) {
    const int last = result.episodes.back().episode;
    cloud = ReadGaussiansPly((EpisodeDir(out_dir, last) / "scene.ply").string());
    progress.Info("idu: resuming after episode " + std::to_string(last + 1) + " of " + std::to_string(o.orbit.episodes));
  }
  const std::vector<Eigen::Vector3d> look_at = LookAtGrid(core, o.orbit.grid, surface_height_m, MedianHeight(cloud));
  std::vector<TrainView> mixed = satellite;  // each episode appends its refined views to these
  for (int k = static_cast<int>(result.episodes.size()); k < o.orbit.episodes; ++k) {
    IduEpisode ep;
    ep.episode = k;
    ep.elevation_deg = EpisodeElevationDeg(o.orbit, k);
    ep.radius_m = EpisodeRadiusM(o.orbit, core, k);
    const fs::path dir = EpisodeDir(out_dir, k);
    fs::remove_all(dir);  // a killed episode's partial files
    fs::create_directories(dir / "renders");
    fs::create_directories(dir / "refined");
    const std::vector<OrbitView> views = EpisodeViews(o.orbit, core, look_at, k);
    ep.views = static_cast<int>(views.size());
    WriteFileAtomic((dir / "cameras.json").string(), OrbitCamerasJson(views, enu_origin));
    progress.Info("idu: episode " + std::to_string(k + 1) + "/" + std::to_string(o.orbit.episodes) + ", elevation " +
                  FormatDouble(ep.elevation_deg) + " deg, radius " + FormatDouble(ep.radius_m) + " m, " +
                  std::to_string(views.size()) + " views");
    std::vector<RefineInput> inputs;
    const std::vector<OrbitRender> renders = RenderEpisodeViews(o, train.raster, cloud, views, surface, dir, &inputs, &ep);
    // Refine them.
    Stopwatch refine_clock;
    RefineRequest request = o.request;
    request.samples = o.samples;
    request.seed = o.seed + 104729ull * static_cast<std::uint64_t>(k + 1);
    request.episode = k;
    const std::vector<RefinedSamples> refined = refiner.Refine(cloud, inputs, request, progress);
    if (refined.size() != views.size()) throw Error("idu", "refiner", "returned a different number of views");
    ep.refine_seconds = refine_clock.Seconds();
    // The mixed dataset: the satellite views and this episode's refined orbit views.
    mixed.resize(satellite.size());
    AppendRefinedViews(views, renders, refined, o.samples, &mixed);
    WriteViewPngs(dir / "refined", views, [&](std::size_t v) -> const std::vector<float>& { return refined[v][0]; });
    if (o.fill_holes) {
      const GaussianCloud added = HoleGaussians(renders, refined, o.fill_voxel_m);
      for (std::size_t i = 0; i < added.size(); ++i) cloud.Append(added, i);
      ep.hole_gaussians = added.size();
    }
    Stopwatch train_clock;
    TrainResult trained = TrainGaussians(EpisodeTrainOptions(o, train, k), std::move(cloud), mixed, "", progress,
                                         nullptr, surface);
    cloud = std::move(trained.cloud);
    ep.train_seconds = train_clock.Seconds();
    ep.psnr_test_start_db = trained.series.empty() ? NAN : trained.series.front().psnr_test_db;
    ep.psnr_test_db = trained.series.empty() ? NAN : trained.series.back().psnr_test_db;
    ep.gaussians = cloud.size();
    ep.step_ms = trained.profile.MeanMsByPhase();
    WriteGaussiansPly((dir / "scene.ply").string(), cloud);
    WriteFileAtomic((dir / "episode.json").string(), EpisodeJson(ep).dump(2) + "\n");  // last: the episode is done
    result.episodes.push_back(ep);
  }
  result.cloud = std::move(cloud);
  result.report.seconds = clock.Seconds();
  result.report.metrics["episodes"] = static_cast<double>(result.episodes.size());
  result.report.metrics["gaussians"] = static_cast<double>(result.cloud.size());
  if (!result.episodes.empty()) {
    result.report.metrics["psnr_test_start_db"] = result.episodes.front().psnr_test_start_db;
    result.report.metrics["psnr_test_db"] = result.episodes.back().psnr_test_db;
  }
  return result;
}

std::vector<TrainView> MatchSceneAppearance(const GaussianCloud& scene, std::vector<TrainView> views,
                                            const RasterOptions& raster) {
  for (TrainView& v : views) {
    const RenderOutput<float> r = RenderGaussians(scene, v.camera, raster);
    const std::size_t n = r.alpha.size();
    LineFit fit[3];  // view colour -> render colour, per channel
    for (std::size_t p = 0; p < n; ++p) {
      if (r.alpha[p] < 0.5f || (!v.valid.empty() && !v.valid[p])) continue;
      for (int c = 0; c < 3; ++c) fit[c].Add(v.rgb[3 * p + c], r.rgb[3 * p + c]);
    }
    const std::size_t used = static_cast<std::size_t>(fit[0].n);
    if (used < n / 10 || used < 2) continue;
    for (int c = 0; c < 3; ++c) {
      constexpr double kMinVariance = 1e-6;  // a flat channel: no gain to fit
      if (fit[c].VarianceA() < kMinVariance) continue;
      const double gain = fit[c].Gain(), offset = fit[c].Offset(gain);
      for (std::size_t p = 0; p < n; ++p)
        v.rgb[3 * p + c] = std::clamp(static_cast<float>(gain * v.rgb[3 * p + c] + offset), 0.0f, 1.0f);
    }
  }
  return views;
}

void IduAutoOptions::Check() const { CheckOptionRanges(*this, "idu", "auto"); }

IduDecision DecideIdu(Switch mode, const IduAutoOptions& o, const std::vector<Eigen::Vector3f>& points,
                      const std::vector<std::uint8_t>& filled, double cell_m) {
  IduDecision d;
  if (mode != Switch::kAuto) {
    // Measured all the same, so that reports compare tiles alike.
    d = DecideIdu(Switch::kAuto, o, points, filled, cell_m);
    d.on = mode == Switch::kOn;
    d.why = std::string("idu.mode is '") + EnumName(mode) + "'";
    return d;
  }
  if (points.empty() || !(cell_m > 0)) {
    d.why = "no dense heights (empty or degenerate tile): nothing to render";
    return d;
  }
  // The dense cells on their grid.
  double min_x = 1e300, min_y = 1e300, max_x = -1e300, max_y = -1e300;
  for (const auto& p : points) {
    min_x = std::min<double>(min_x, p.x());
    min_y = std::min<double>(min_y, p.y());
    max_x = std::max<double>(max_x, p.x());
    max_y = std::max<double>(max_y, p.y());
  }
  const int nx = static_cast<int>(std::lround((max_x - min_x) / cell_m)) + 1;
  const int ny = static_cast<int>(std::lround((max_y - min_y) / cell_m)) + 1;
  std::vector<float> height(static_cast<std::size_t>(nx) * ny, NAN);
  std::size_t measured = 0;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const int i = static_cast<int>(std::lround((points[k].x() - min_x) / cell_m));
    const int j = static_cast<int>(std::lround((points[k].y() - min_y) / cell_m));
    height[static_cast<std::size_t>(j) * nx + i] = points[k].z();
    if (k >= filled.size() || !filled[k]) ++measured;
  }
  d.measured_fraction = static_cast<double>(measured) / height.size();
  // Facade area: every step of at least step_m between 4-neighbours is a
  // wall of that height and one cell wide.
  double facade_m2 = 0;
  std::size_t cells = 0;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const float h = height[static_cast<std::size_t>(j) * nx + i];
      if (!std::isfinite(h)) continue;
      ++cells;
      for (const auto& [di, dj] : {std::pair{1, 0}, std::pair{0, 1}}) {
        if (i + di >= nx || j + dj >= ny) continue;
        const float g = height[static_cast<std::size_t>(j + dj) * nx + i + di];
        if (std::isfinite(g) && std::abs(g - h) >= o.step_m) facade_m2 += std::abs(g - h) * cell_m;
      }
    }
  }
  d.facade_ratio = cells ? facade_m2 / (cells * cell_m * cell_m) : 0.0;
  if (d.measured_fraction < o.min_measured_fraction) {
    d.why = "only " + FormatDouble(100 * d.measured_fraction) + " % of the ground was measured (< " +
            FormatDouble(100 * o.min_measured_fraction) + " %: water, featureless or empty)";
  } else if (d.facade_ratio < o.min_facade_ratio) {
    d.why = "flat or low-rise: " + FormatDouble(d.facade_ratio) + " m2 of facade (steps >= " + FormatDouble(o.step_m) +
            " m) per m2 of ground (< " + FormatDouble(o.min_facade_ratio) + ")";
  } else {
    d.on = true;
    d.why = FormatDouble(d.facade_ratio) + " m2 of facade (steps >= " + FormatDouble(o.step_m) + " m) per m2 of ground (>= " +
            FormatDouble(o.min_facade_ratio) + ")";
  }
  return d;
}

}  // namespace skyfall
