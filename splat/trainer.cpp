#include "splat/trainer.h"

#include "core/crash_point.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <sstream>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "splat/losses.h"
#include "splat/optimizer_state.h"
#include "splat/train_evaluation.h"
#include "splat/ply.h"

#include <Eigen/Geometry>

namespace skyfall {
namespace {

namespace fs = std::filesystem;

double InverseSigmoid(double p) { return std::log(p / (1 - p)); }

// Adds the geometry and opacity gradients of an extra view (a pseudo or
// nadir view, which supervises no colour) to the step's gradients.
// Only the Gaussians the extra view rendered (`seen`) have a gradient from
// it; a 192 px regularizer view sees part of the cloud (half of it in
// step_bench's compact scene, less in a 256 m tile).
void AddGeometryGradients(const GaussianGradients<float>& extra, const RasterState<float>& seen,
                          GaussianGradients<float>* g) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, extra.d.means.size(), 4096),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i < range.end(); ++i) {
                        if (!seen.radius_px[i]) continue;
                        g->d.means[i] += extra.d.means[i];
                        g->d.log_scales[i] += extra.d.log_scales[i];
                        g->d.rotations[i] += extra.d.rotations[i];
                        g->d.opacity_logits[i] += extra.d.opacity_logits[i];
                      }
                    });
}

// The surface anchor on one rendered training view (the surface's depth is
// relative to the render's reference depth).
double SurfaceAnchorLoss(const RenderOutput<float>& r, const DepthMap& surface, const TrainOptions& o,
                         std::vector<float>* d_alpha, std::vector<float>* d_depth) {
  const SurfaceAnchorOptions anchor{o.surface.lambda_depth, o.surface.lambda_alpha, o.surface.huber_m};
  return SurfaceAnchorLoss(r.depth, r.alpha, surface.depth, surface.valid, anchor, d_depth, d_alpha,
                           surface.weight.empty() ? nullptr : &surface.weight);
}

// Gaussians on the surface held to its height (SurfaceHeightLoss); adds
// the gradient of the centres' heights to `d`.
double SurfaceHeightTerm(const SurfaceDepthPrior& surface, const GaussianCloud& cloud, const TrainOptions& o,
                         GaussianCloud* d) {
  const std::size_t n = cloud.size();
  std::vector<float> z(n), height(n), weight(n), d_z(n, 0.0f);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const Eigen::Vector3f& m = cloud.means[i];
      z[i] = m.z();
      height[i] = static_cast<float>(surface.HeightAt(m.x(), m.y()));
      weight[i] = surface.WeightAt(m.x(), m.y());
    }
  });
  const double loss = SurfaceHeightLoss(z, height, {o.surface.lambda_height, o.surface.height_band_m}, &d_z, &weight);
  for (std::size_t i = 0; i < n; ++i) d->means[i].z() += d_z[i];
  return loss;
}

// A training view: a satellite view, or with probability `synthetic_fraction`
// a synthetic one when there are any (the satellite-only stream of random
// numbers stays as it was).
int PickView(const std::vector<int>& satellite, const std::vector<int>& synthetic, double synthetic_fraction,
             std::mt19937_64& rng) {
  if (!synthetic.empty()) {
    const double u = static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0);
    if (u < synthetic_fraction) return synthetic[rng() % synthetic.size()];
  }
  return satellite[rng() % satellite.size()];
}

// The photometric loss of a view, averaged over its colour targets.
double ViewPhotometricLoss(const RenderOutput<float>& r, const TrainView& view, const PhotometricLossOptions& o,
                           std::vector<float>* d_rgb) {
  std::vector<const std::vector<float>*> targets = {&view.rgb};
  for (const auto& extra : view.extra_rgb) targets.push_back(&extra);
  return PhotometricLossMean(r.rgb, targets, view.camera.width_px, view.camera.height_px, o, d_rgb);
}

// lambda times the Pearson depth loss against the view's depth target, over
// the pixels where the target is finite and the render is opaque.
double ViewDepthLoss(const RenderOutput<float>& r, const TrainView& view, double lambda, std::vector<float>* d_depth) {
  std::vector<unsigned char> valid(view.depth_target.size());
  for (std::size_t k = 0; k < valid.size(); ++k)
    valid[k] = std::isfinite(view.depth_target[k]) && r.alpha[k] > 0.5f && (view.valid.empty() || view.valid[k]);
  const double loss = lambda * PearsonDepthLoss(r.depth, view.depth_target, valid, d_depth);
  for (float& g : *d_depth) g *= static_cast<float>(lambda);
  return loss;
}

double SceneExtent(const GaussianCloud& c) {
  if (c.size() == 0) return 1.0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : c.means) centre += p.cast<double>();
  centre /= static_cast<double>(c.size());
  double r = 0;
  for (const auto& p : c.means) r = std::max(r, (p.cast<double>() - centre).norm());
  return std::max(1.0, 1.1 * r);
}

// The view whose appearance the exported cloud is fused with: the named one
// (checked before training starts), else -1 for "the typical one".
int AppearanceViewIndex(const TrainOptions& o, const std::vector<TrainView>& views) {
  if (!o.appearance.enabled || o.appearance_image.empty()) return -1;
  for (int k = 0; k < static_cast<int>(views.size()); ++k)
    if (views[k].name == o.appearance_image && !views[k].held_out) return k;
  throw Error("train", "appearance_image", o.appearance_image + " is not a training view");
}

// The view the exported cloud is fused for; -1 without the appearance model.
int ExportView(const AppearanceState& a, int fused_view, const std::vector<int>& train_ids) {
  if (!a.enabled) return -1;
  return fused_view >= 0 ? fused_view : TypicalImage(a.model, train_ids);
}

// The plain 3DGS cloud to write: with the appearance model, fused for `view`.
GaussianCloud ExportCloud(const GaussianCloud& cloud, const AppearanceState& a, int view) {
  if (!a.enabled) return cloud;
  return FuseAppearance(a.model, a.model.image_embeddings.col(view), cloud);
}

}  // namespace

int DistinctAcquisitionDates(const std::vector<TrainView>& views) {
  std::set<std::string> dates;
  for (const TrainView& v : views)
    if (!v.held_out) dates.insert(v.acquisition_time.substr(0, 10));
  return static_cast<int>(dates.size());
}

void TrainOptions::Check() const {
  CheckOptionRanges(*this, "train");  // every option's declared range (Visit, trainer.h)
  // Not options (the synthesis stage sets them from idu.*), so no range is
  // declared for them; a library caller may still set them.
  if (!(synthetic_fraction >= 0 && synthetic_fraction <= 1))
    throw Error("train", "synthetic_fraction", FormatDouble(synthetic_fraction) + " is out of range [0, 1]");
  if (!(lambda_view_depth >= 0 && std::isfinite(lambda_view_depth)))
    throw Error("train", "lambda_view_depth", FormatDouble(lambda_view_depth) + " must be a finite value >= 0");
  raster.Check();  // min_alpha below max_alpha
}

namespace {

// Mean distance from each point to its 3 nearest neighbours (a sweep over
// the points sorted by x; SfM clouds are ~1e4 points).
std::vector<double> NeighbourDistances(const std::vector<Eigen::Vector3f>& points) {
  std::vector<std::size_t> order(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return points[a].x() < points[b].x(); });
  std::vector<std::size_t> rank(points.size());
  for (std::size_t k = 0; k < order.size(); ++k) rank[order[k]] = k;
  std::vector<double> out(points.size(), 1.0);
  for (std::size_t i = 0; i < points.size(); ++i) {
    std::array<float, 3> best = {1e30f, 1e30f, 1e30f};
    // Sweep outwards in x until the x gap alone exceeds the third-best distance.
    for (int dir : {-1, 1}) {
      for (long k = static_cast<long>(rank[i]) + dir; k >= 0 && k < static_cast<long>(order.size()); k += dir) {
        const Eigen::Vector3f& q = points[order[k]];
        const float dx = q.x() - points[i].x();
        if (dx * dx > best[2]) break;
        const float d2 = (q - points[i]).squaredNorm();
        if (d2 < best[2]) {
          best[2] = d2;
          std::sort(best.begin(), best.end());
        }
      }
    }
    double mean = 0;
    int n = 0;
    for (float d2 : best)
      if (d2 < 1e29f) {
        mean += std::sqrt(d2);
        ++n;
      }
    if (n) out[i] = mean / n;
  }
  return out;
}

}  // namespace

GaussianCloud InitializeFromPoints(const std::vector<Eigen::Vector3f>& points,
                                   const std::vector<Eigen::Vector3f>& colours, double max_scale_m,
                                   int max_pieces_per_point) {
  if (!(max_scale_m > 0)) throw Error("train", "init max scale", FormatDouble(max_scale_m) + " m must be > 0");
  if (max_pieces_per_point < 1 || max_pieces_per_point > 64) {
    throw Error("train", "init pieces per point", std::to_string(max_pieces_per_point) + " is not in 1..64");
  }
  if (points.empty()) throw Error("train", "init", "no SfM points to start from");
  const std::vector<double> spacing = NeighbourDistances(points);
  std::mt19937 rng(12345);  // fixed: the same SfM points give the same start
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  GaussianCloud c;
  auto add = [&](const Eigen::Vector3f& mean, float scale, const Eigen::Vector3f& colour) {
    const std::size_t k = c.size();
    c.resize(k + 1);
    c.means[k] = mean;
    c.log_scales[k] = Eigen::Vector3f::Constant(std::log(scale));
    c.rotations[k] = Eigen::Vector4f(1, 0, 0, 0);
    c.opacity_logits[k] = static_cast<float>(InverseSigmoid(0.1));
    c.sh[k].fill(0.0f);
    for (int ch = 0; ch < 3; ++ch) c.sh[k][ch * 4] = static_cast<float>(ShDcFromColour(colour[ch]));
  };
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double d = std::max(0.05, spacing[i]);
    const float scale = static_cast<float>(std::min(max_scale_m, d));
    const double coverage = d / scale;  // > 1 where the cap bit
    const int pieces = std::min<double>(max_pieces_per_point, std::ceil(coverage * coverage - 1e-9));
    add(points[i], scale, colours[i]);
    for (int k = 1; k < pieces; ++k) {
      // Uniform over the disc of radius d/2 around the point.
      const float r = static_cast<float>(0.5 * d) * std::sqrt(unit(rng)), phi = 6.2831853f * unit(rng);
      add(points[i] + Eigen::Vector3f(r * std::cos(phi), r * std::sin(phi), 0.0f), scale, colours[i]);
    }
  }
  return c;
}

double StepProfile::StepMs() const {
  double ms = 0;
  for (int k = 0; k < kCount; ++k) ms += MeanMs(k);
  return ms;
}

std::vector<std::pair<std::string, double>> StepProfile::MeanMsByPhase() const {
  std::vector<std::pair<std::string, double>> out = {{"step", StepMs()}};
  for (int k = 0; k < kCount; ++k) out.emplace_back(kPhases[k], MeanMs(k));
  return out;
}

namespace {

// Adds the time since the previous lap to one phase of a StepProfile.
class PhaseClock {
 public:
  explicit PhaseClock(StepProfile* profile) : profile_(profile), last_(std::chrono::steady_clock::now()) {}
  void Lap(int phase) {
    const auto now = std::chrono::steady_clock::now();
    profile_->seconds[phase] += std::chrono::duration<double>(now - last_).count();
    last_ = now;
  }
  // Restarts the clock without counting the time since the previous lap.
  void Skip() { last_ = std::chrono::steady_clock::now(); }

 private:
  StepProfile* profile_;
  std::chrono::steady_clock::time_point last_;
};

// In the order of StepProfile::kPhases.
enum Phase { kAppearance, kRasterFwd, kLoss, kRasterBwd, kRegularizerViews, kOptimizer, kDensify, kEvaluation, kBookkeeping,
             kPhaseCount };
static_assert(kPhaseCount == StepProfile::kCount, "StepProfile::kPhases and Phase list the same phases");

}  // namespace

std::size_t DropNonFiniteGradients(GaussianGradients<float>* gradients) {
  GaussianCloud* g = &gradients->d;
  std::vector<ColourAffine<float>>& affine = gradients->d_colour_affine;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, g->size(), 4096), std::size_t{0},
      [g, &affine](const tbb::blocked_range<std::size_t>& range, std::size_t dropped) {
        for (std::size_t i = range.begin(); i < range.end(); ++i) {
          const bool finite = g->means[i].allFinite() && g->log_scales[i].allFinite() && g->rotations[i].allFinite() &&
                              std::isfinite(g->opacity_logits[i]) &&
                              std::all_of(g->sh[i].begin(), g->sh[i].end(), [](float v) { return std::isfinite(v); }) &&
                              (affine.empty() || affine[i].allFinite());
          if (finite) continue;
          g->means[i].setZero();
          g->log_scales[i].setZero();
          g->rotations[i].setZero();
          g->opacity_logits[i] = 0.0f;
          g->sh[i].fill(0.0f);
          if (!affine.empty()) affine[i].setZero();
          ++dropped;
        }
        return dropped;
      },
      std::plus<>());
}

namespace {

// The satellite training views and the synthetic ones, by index; checks
// that every view's buffers match its camera.
struct ViewIds {
  std::vector<int> train, synthetic;
};

ViewIds SplitTrainingViews(const TrainOptions& o, const std::vector<TrainView>& views) {
  ViewIds ids;
  for (int k = 0; k < static_cast<int>(views.size()); ++k) {
    if (views[k].held_out) continue;
    (views[k].synthetic ? ids.synthetic : ids.train).push_back(k);
  }
  if (ids.train.empty()) throw Error("train", "views", "no training view (all are held out or none given)");
  for (const TrainView& v : views) {
    if (v.rgb.size() != 3u * v.camera.width_px * v.camera.height_px) {
      throw Error("train", v.name, "image size does not match its camera");
    }
    if (!v.valid.empty() && v.valid.size() != v.rgb.size() / 3) throw Error("train", v.name, "mask size does not match its image");
    for (const auto& extra : v.extra_rgb)
      if (extra.size() != v.rgb.size()) throw Error("train", v.name, "a further colour target differs in size");
    if (!v.depth_target.empty() && v.depth_target.size() != v.rgb.size() / 3)
      throw Error("train", v.name, "depth target size does not match its image");
  }
  if (o.appearance.enabled && !ids.synthetic.empty())
    throw Error("train", "appearance", "synthetic views have no acquisition to embed: train them without the appearance model");
  return ids;
}

// One training run: the state a checkpoint saves and the parts of a step.
class TrainingRun {
 public:
  TrainingRun(const TrainOptions& o, GaussianCloud cloud, const std::vector<TrainView>& views, DepthPrior* depth_prior,
              const SurfaceDepthPrior* surface, Progress& progress, TrainResult* result)
      : o_(o),
        views_(views),
        ids_(SplitTrainingViews(o, views)),
        depth_prior_(depth_prior),
        surface_(surface),
        progress_(progress),
        result_(*result),
        cloud_(Gather(cloud, SpatialOrder(cloud))),
        rng_(o.seed),
        // The extent scales the position learning rate and the split size. It
        // is taken from the initial cloud (the caller passes the same one
        // when resuming), so a resumed run uses the same value.
        extent_(SceneExtent(cloud_)),
        density_(o.density, extent_),
        phase_(&result->profile) {
    adam_.Resize(cloud_.size());
    if (o.appearance.enabled) {
      appearance_.enabled = true;
      appearance_.model = InitAppearance(o.appearance, static_cast<int>(views.size()), cloud_.size(), o.seed);
      appearance_.m = appearance_.model.ZerosLike();
      appearance_.v = appearance_.model.ZerosLike();
    }
    for (const auto& p : cloud_.means) scene_centre_ += p.cast<double>();
    scene_centre_ /= std::max<std::size_t>(1, cloud_.size());
    density_.stats().Reset(cloud_.size());
  }

  // Continues from a checkpoint written with the same settings; returns the
  // step it was written at.
  int ResumeFrom(const std::string& ck_path) {
    Checkpoint ck = LoadCheckpoint(ck_path);
    cloud_ = std::move(ck.cloud);
    adam_ = std::move(ck.adam);
    std::istringstream(ck.rng_state) >> rng_;
    result_.series = std::move(ck.series);
    density_.stats() = std::move(ck.stats);
    loss_sum_ = ck.loss_sum;
    loss_count_ = static_cast<int>(ck.loss_count);
    if (ck.appearance.enabled != o_.appearance.enabled ||
        (ck.appearance.enabled && (ck.appearance.model.image_embeddings.cols() != static_cast<Eigen::Index>(views_.size()) ||
                                   std::string(ck.appearance.model.kind()) != EnumName(o_.appearance.model)))) {
      throw Error("train", ck_path,
                  "was written with different appearance-model settings (on/off, model or image count); delete it to "
                  "start again");
    }
    appearance_ = std::move(ck.appearance);
    return ck.iteration;
  }

  // The starting point of the error-versus-time series, and the surface's
  // depth in each anchored training view, computed once before the steps.
  void Prepare() {
    previous_seconds_ = result_.series.empty() ? 0.0 : result_.series.back().seconds;
    if (result_.series.empty()) {
      TrainSample s;
      s.psnr_test_db = HeldOutPsnr(cloud_, views_, o_.raster, appearance_, ids_.train);
      s.gaussians = cloud_.size();
      s.loss = std::numeric_limits<double>::quiet_NaN();
      result_.series.push_back(s);
    }
    anchored_ = surface_ && (o_.surface.lambda_depth > 0 || o_.surface.lambda_alpha > 0);
    surface_depth_.resize(views_.size());
    if (anchored_) {
      tbb::parallel_for(std::size_t{0}, ids_.train.size(), [&](std::size_t k) {
        const PinholeCamera& cam = views_[ids_.train[k]].camera;
        surface_depth_[ids_.train[k]] = surface_->DepthRelativeTo(cam, cam.cam_from_world_translation.z());
      });
    }
    phase_.Skip();
  }

  void Step(int it, const std::string& checkpoint_dir, const std::string& ck_path, int fused_view) {
    ++result_.profile.steps;
    phase_.Lap(kBookkeeping);  // the end of the previous step
    const int view_id = PickView(ids_.train, ids_.synthetic, o_.synthetic_fraction, rng_);
    StepGradients s = ViewGradients(view_id);
    s.loss += RegularizerTerms(it, &s.g);
    phase_.Lap(kRegularizerViews);
    loss_sum_ += s.loss;
    ++loss_count_;
    Optimize(it, &s);
    phase_.Lap(kOptimizer);
    if (density_.Due(it)) FollowGaussians(density_.Densify(it, &cloud_, &adam_.m, &adam_.v, rng_));
    if (density_.MergeDue(it, o_.iterations)) FollowGaussians(density_.MergeCoincident(&cloud_, &adam_.m, &adam_.v));
    phase_.Lap(kDensify);
    if (it % o_.eval_interval == 0 || it == o_.iterations) RecordSample(it);
    if (it == SurfaceIteration()) KeepSurface(it, checkpoint_dir, fused_view);
    phase_.Lap(kEvaluation);
    if (!ck_path.empty() && (it % o_.checkpoint_interval == 0 || it == o_.iterations))
      SaveState(it, checkpoint_dir, ck_path, fused_view);
  }

  // The step whose scene is kept as the DSMs' surface; 0 for none.
  int SurfaceIteration() const {
    return o_.surface_at > 0 ? std::max(1, static_cast<int>(std::lround(o_.surface_at * o_.iterations))) : 0;
  }

  // Exported as the final cloud is, and written (before the step's
  // checkpoint) beside the checkpoints, from where a run resumed after this
  // step takes it back (ResumeSurface).
  void KeepSurface(int it, const std::string& checkpoint_dir, int fused_view) {
    result_.surface = ExportCloud(cloud_, appearance_, ExportView(appearance_, fused_view, ids_.train));
    result_.surface_iteration = it;
    if (checkpoint_dir.empty()) return;
    fs::create_directories(checkpoint_dir);
    WriteGaussiansPly(SurfacePath(checkpoint_dir), *result_.surface);
  }

  void ResumeSurface(int resumed_at, const std::string& checkpoint_dir) {
    const int at = SurfaceIteration();
    if (at == 0 || resumed_at < at) return;
    const std::string path = SurfacePath(checkpoint_dir);
    if (!fs::exists(path))
      throw Error("train", path, "missing: the checkpoint is past step " + std::to_string(at) +
                                     ", whose surface it needs; delete the checkpoints to start again");
    result_.surface = ReadGaussiansPly(path);
    result_.surface_iteration = at;
  }

  static std::string SurfacePath(const std::string& checkpoint_dir) {
    return (fs::path(checkpoint_dir) / "surface.ply").string();
  }

  // Per-Gaussian state kept outside the cloud follows a densification or a
  // merge: `source` names the Gaussian each one comes from.
  void FollowGaussians(const std::vector<std::size_t>& source) {
    if (!appearance_.enabled) return;
    for (AppearanceModel* a : {&appearance_.model, &appearance_.m, &appearance_.v}) a->GatherGaussians(source);
  }

  // The exported cloud and the report's figures.
  void Finish(int fused_view) {
    phase_.Lap(kBookkeeping);
    progress_.End();
    const int export_view = ExportView(appearance_, fused_view, ids_.train);
    result_.cloud = ExportCloud(cloud_, appearance_, export_view);
    if (export_view >= 0) result_.appearance_image = views_[export_view].name;
    std::map<std::string, double>& m = result_.report.metrics;
    m["gaussians"] = static_cast<double>(result_.cloud.size());
    if (!result_.series.empty()) m["psnr_test_db"] = result_.series.back().psnr_test_db;
    m["nonfinite_gradient_steps"] = static_cast<double>(nonfinite_steps_);
    m["nonfinite_gradient_gaussians"] = static_cast<double>(nonfinite_gaussians_);
    // A run resumed from its last checkpoint has no step left to render them.
    if (!held_out_rendered_) result_.held_out = HeldOutRenders(cloud_, views_, o_.raster, appearance_, ids_.train);
    m["psnr_test_fitted_db"] = MeanOverHeldOut(result_.held_out, &HeldOutRender::fitted_psnr_db);
    // Without the model there is no embedding to choose: psnr_test_db is the figure.
    if (appearance_.enabled && !result_.held_out.empty())
      m["psnr_test_best_embedding_db"] = MeanOverHeldOut(result_.held_out, &HeldOutRender::best_embedding_psnr_db);
    m["psnr_train_db"] = TrainingPsnr(cloud_, views_, o_.raster, appearance_, ids_.train);
    const bool any_held_out = std::any_of(views_.begin(), views_.end(), [](const TrainView& v) { return v.held_out; });
    if (appearance_.enabled && any_held_out) {
      m["psnr_test_mean_embedding_db"] =
          HeldOutPsnr(cloud_, views_, o_.raster, appearance_, ids_.train, /*by_date=*/false);
      for (const auto& [name, n] : HeldOutEmbeddingRules(views_, appearance_, ids_.train)) m[name] = n;
    }
  }

 private:
  struct StepGradients {
    double loss = 0;
    GaussianGradients<float> g;
    AppearanceModel appearance_grad;
    std::size_t dropped = 0;  // Gaussians with a non-finite gradient
  };

  // The photometric, view-depth and anchor losses on one view and their
  // gradients (the appearance model's too).
  StepGradients ViewGradients(int view_id) {
    const TrainView& view = views_[view_id];
    std::vector<ColourAffine<float>> affine;
    Eigen::VectorXf embedding;
    AppearanceActivations<float> activations;
    if (appearance_.enabled) {
      embedding = appearance_.model.image_embeddings.col(view_id);
      affine = EvaluateAppearance(appearance_.model, embedding, cloud_, &activations);
    }
    phase_.Lap(kAppearance);
    const std::vector<ColourAffine<float>>* colour_affine = appearance_.enabled ? &affine : nullptr;
    const RenderOutput<float> r = RenderGaussians(cloud_, view.camera, o_.raster, colour_affine);
    phase_.Lap(kRasterFwd);
    StepGradients s;
    std::vector<float> d_rgb;
    s.loss = ViewPhotometricLoss(r, view, PhotometricLossOptions{o_.lambda_dssim}, &d_rgb);
    for (std::size_t p = 0; p < view.valid.size(); ++p) {
      if (!view.valid[p]) d_rgb[3 * p] = d_rgb[3 * p + 1] = d_rgb[3 * p + 2] = 0.0f;  // no data: no pull
    }
    std::vector<float> d_alpha, d_depth;
    if (!view.depth_target.empty() && o_.lambda_view_depth > 0)
      s.loss += ViewDepthLoss(r, view, o_.lambda_view_depth, &d_depth);
    if (anchored_ && !view.synthetic) {
      std::vector<float> anchor_depth;
      s.loss += SurfaceAnchorLoss(r, surface_depth_[view_id], o_, &d_alpha, &anchor_depth);
      if (d_depth.empty()) {
        d_depth = std::move(anchor_depth);
      } else {  // a view with a depth target too: both gradients count
        for (std::size_t p = 0; p < d_depth.size(); ++p) d_depth[p] += anchor_depth[p];
      }
    }
    phase_.Lap(kLoss);
    s.g = BackwardGaussians(cloud_, view.camera, o_.raster, r, d_rgb, d_alpha, d_depth, colour_affine);
    // Before the appearance model's gradient is built from them.
    s.dropped = DropNonFiniteGradients(&s.g);
    // The view-space gradients of the Gaussians this view saw (the
    // regularizers below add none to them).
    density_.Accumulate(r.state.radius_px, s.g.mean2d_norm, view.camera.width_px);
    phase_.Lap(kRasterBwd);
    if (appearance_.enabled) {
      s.appearance_grad = appearance_.model.ZerosLike();
      s.appearance_grad.image_embeddings.col(view_id) = BackwardAppearance(
          appearance_.model, embedding, cloud_, s.g.d_colour_affine, &s.appearance_grad, &s.g.d.sh, &activations);
    }
    phase_.Lap(kAppearance);
    return s;
  }

  // The regularizers: entropy on opacities, centres held to the surface,
  // the anchor on a nadir patch and the pseudo view's depth prior. Their
  // gradients go into `g`; returns their loss.
  double RegularizerTerms(int it, GaussianGradients<float>* g) {
    double loss = 0;
    if (o_.lambda_opacity > 0 && it >= o_.opacity_reg_from) {
      std::vector<float> d_op;
      loss += o_.lambda_opacity * OpacityEntropy(cloud_.opacity_logits, &d_op);
      for (std::size_t i = 0; i < cloud_.size(); ++i)
        g->d.opacity_logits[i] += static_cast<float>(o_.lambda_opacity) * d_op[i];
    }
    if (surface_ && o_.surface.lambda_height > 0) loss += SurfaceHeightTerm(*surface_, cloud_, o_, &g->d);
    phase_.Lap(kLoss);
    if (anchored_ && o_.surface.nadir_interval > 0 && it % o_.surface.nadir_interval == 0) {
      // A nadir patch around a look-at point drawn like the pseudo views'.
      std::mt19937_64 pick(0xA11C0000ull + static_cast<std::uint64_t>(it));
      std::normal_distribution<double> offset(0.0, o_.pseudo.look_at_sigma_m);
      const Eigen::Vector3d look_at = scene_centre_ + Eigen::Vector3d(offset(pick), offset(pick), 0.0);
      constexpr double kNadirHeightM = 1.0e5;  // far: rays tilt < 0.1 deg over the patch
      const PinholeCamera nadir = NadirCamera(look_at, o_.surface.nadir_gsd_m, o_.surface.nadir_size_px, kNadirHeightM);
      const RenderOutput<float> nr = RenderGaussians(cloud_, nadir, o_.raster);
      const DepthMap target = surface_->NadirDepthRelativeTo(nadir, nr.reference_depth_m);
      std::vector<float> n_alpha, n_depth;
      loss += SurfaceAnchorLoss(nr, target, o_, &n_alpha, &n_depth);
      AddGeometryGradients(BackwardGaussians(cloud_, nadir, o_.raster, nr, {}, n_alpha, n_depth), nr.state, g);
    }
    if (depth_prior_ && o_.pseudo_interval > 0 && it % o_.pseudo_interval == 0) {
      // Pseudo view: the same sample for the same iteration, so resumes match.
      const PinholeCamera pc = SamplePseudoCamera(o_.pseudo, scene_centre_, static_cast<std::uint64_t>(it));
      const RenderOutput<float> pr = RenderGaussians(cloud_, pc, o_.raster);
      DepthMap prior = depth_prior_->Estimate(pc, pr.rgb);
      for (std::size_t k = 0; k < prior.valid.size(); ++k) prior.valid[k] &= pr.alpha[k] > 0.5f;
      std::vector<float> d_depth;
      loss += o_.lambda_depth * PearsonDepthLoss(pr.depth, prior.depth, prior.valid, &d_depth);
      for (float& v : d_depth) v *= static_cast<float>(o_.lambda_depth);
      AddGeometryGradients(BackwardGaussians(cloud_, pc, o_.raster, pr, {}, {}, d_depth), pr.state, g);
    }
    return loss;
  }

  // Adam on the Gaussians (and the appearance model), the centres' rate
  // decaying exponentially; Gaussians with a non-finite gradient skip it.
  void Optimize(int it, StepGradients* s) {
    const double t = static_cast<double>(it) / o_.iterations;
    const double lr_mean = extent_ * std::exp((1 - t) * std::log(o_.lr.mean_initial) + t * std::log(o_.lr.mean_final));
    s->dropped += DropNonFiniteGradients(&s->g);  // and those the regularizer views added
    if (s->dropped > 0) {
      if (nonfinite_steps_ == 0) {
        progress_.Warn("splat train: step " + std::to_string(it) + ": " + std::to_string(s->dropped) +
                       " Gaussian(s) with a non-finite gradient; their update is skipped (counted in the train report)");
      }
      nonfinite_gaussians_ += s->dropped;
      ++nonfinite_steps_;
    }
    AdamStep(cloud_, adam_, s->g.d, o_, lr_mean);
    if (appearance_.enabled) AdamStepAppearance(appearance_, s->appearance_grad, adam_.step, o_.appearance);
  }

  void RecordSample(int it) {
    TrainSample s;
    s.iteration = it;
    s.seconds = previous_seconds_ + clock_.Seconds();
    s.loss = loss_sum_ / std::max(1, loss_count_);
    if (it == o_.iterations) {  // the report's renders are the last point's: rendered once
      // Not a step's work (each held-out view under every training
      // embedding): left out of the step profile, as after the loop.
      phase_.Lap(kEvaluation);
      result_.held_out = HeldOutRenders(cloud_, views_, o_.raster, appearance_, ids_.train);
      phase_.Skip();
      held_out_rendered_ = true;
      s.psnr_test_db = MeanOverHeldOut(result_.held_out, &HeldOutRender::psnr_db);
    } else {
      s.psnr_test_db = HeldOutPsnr(cloud_, views_, o_.raster, appearance_, ids_.train);
    }
    s.gaussians = cloud_.size();
    result_.series.push_back(s);
    loss_sum_ = 0;
    loss_count_ = 0;
  }

  void SaveState(int it, const std::string& checkpoint_dir, const std::string& ck_path, int fused_view) {
    std::ostringstream state;
    state << rng_;
    SaveCheckpoint(ck_path, {it, cloud_, adam_, state.str(), result_.series, density_.stats(), loss_sum_, loss_count_,
                             appearance_});
    if (o_.keep_snapshots) {
      WriteGaussiansPly((fs::path(checkpoint_dir) / "snapshots" / ("scene_" + std::to_string(it) + ".ply")).string(),
                        ExportCloud(cloud_, appearance_, ExportView(appearance_, fused_view, ids_.train)));
    }
  }

  const TrainOptions& o_;
  const std::vector<TrainView>& views_;
  const ViewIds ids_;
  DepthPrior* depth_prior_;
  const SurfaceDepthPrior* surface_;
  Progress& progress_;
  TrainResult& result_;
  Stopwatch clock_;
  GaussianCloud cloud_;
  Adam adam_;
  std::mt19937_64 rng_;
  AppearanceState appearance_;
  const double extent_;
  Eigen::Vector3d scene_centre_ = Eigen::Vector3d::Zero();
  DensityControl density_;
  PhaseClock phase_;
  double loss_sum_ = 0;
  int loss_count_ = 0;
  double previous_seconds_ = 0;
  bool anchored_ = false;
  std::vector<DepthMap> surface_depth_;
  std::size_t nonfinite_gaussians_ = 0, nonfinite_steps_ = 0;  // DropNonFiniteGradients, this run
  bool held_out_rendered_ = false;
};

}  // namespace

TrainResult TrainGaussians(const TrainOptions& o, GaussianCloud cloud, const std::vector<TrainView>& views,
                           const std::string& checkpoint_dir, Progress& progress, DepthPrior* depth_prior,
                           const SurfaceDepthPrior* surface) {
  o.Check();
  Stopwatch clock;
  TrainResult result;
  result.report.stage = "splat_train";
  TrainingRun run(o, std::move(cloud), views, depth_prior, surface, progress, &result);
  const int fused_view = AppearanceViewIndex(o, views);
  const std::string ck_path = checkpoint_dir.empty() ? "" : (fs::path(checkpoint_dir) / "checkpoint.bin").string();
  int start = 0;
  if (!ck_path.empty() && fs::exists(ck_path)) {
    start = run.ResumeFrom(ck_path);
    run.ResumeSurface(start, checkpoint_dir);
  }
  result.start_iteration = start;
  run.Prepare();
  progress.Begin("splat train", static_cast<std::size_t>(o.iterations));
  for (int it = start + 1; it <= o.iterations; ++it) {
    run.Step(it, checkpoint_dir, ck_path, fused_view);
    CrashPoint("train", it);
    progress.Advance(static_cast<std::size_t>(it), "");
  }
  run.Finish(fused_view);
  result.report.seconds = clock.Seconds();
  return result;
}

}  // namespace skyfall
