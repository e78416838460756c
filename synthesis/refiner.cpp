#include "synthesis/refiner.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>
#include <random>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "splat/rasterizer.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

// A satellite view's rendered surface depth (relative to `reference_m`, NaN
// where the scene holds no surface) for the visibility test.
struct SatelliteDepth {
  std::vector<float> depth;
  double reference_m = 0;
};

SatelliteDepth RenderSatelliteDepth(const GaussianCloud& scene, const TrainView& view, RasterOptions raster) {
  raster.median_depth = true;
  const RenderOutput<float> r = RenderGaussians(scene, view.camera, raster);
  SatelliteDepth out;
  out.reference_m = r.reference_depth_m;
  out.depth.resize(r.alpha.size());
  for (std::size_t k = 0; k < out.depth.size(); ++k) {
    const float median = r.median_depth[k];
    out.depth[k] = std::isfinite(median) ? median : r.alpha[k] > 0.5f ? r.depth[k] : NAN;
  }
  return out;
}

// Bilinear colour of a view at (u, v) (inside the image).
Eigen::Vector3f Bilinear(const TrainView& v, double u, double w) {
  const int W = v.camera.width_px, H = v.camera.height_px;
  const int x0 = std::clamp(static_cast<int>(std::floor(u)), 0, W - 1), y0 = std::clamp(static_cast<int>(std::floor(w)), 0, H - 1);
  const int x1 = std::min(x0 + 1, W - 1), y1 = std::min(y0 + 1, H - 1);
  const float fx = static_cast<float>(std::clamp(u - x0, 0.0, 1.0)), fy = static_cast<float>(std::clamp(w - y0, 0.0, 1.0));
  auto at = [&](int x, int y) {
    const float* p = &v.rgb[3 * (static_cast<std::size_t>(y) * W + x)];
    return Eigen::Vector3f(p[0], p[1], p[2]);
  };
  return (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x1, y0)) + fy * ((1 - fx) * at(x0, y1) + fx * at(x1, y1));
}

// One satellite view's vote for a pixel.
struct Vote {
  int view;
  float weight;
  Eigen::Vector3f colour;
};

float WeightedMedian(std::vector<std::pair<float, float>>& value_weight) {
  std::sort(value_weight.begin(), value_weight.end());
  float total = 0;
  for (const auto& vw : value_weight) total += vw.second;
  float acc = 0;
  for (const auto& vw : value_weight) {
    acc += vw.second;
    if (acc >= 0.5f * total) return vw.first;
  }
  return value_weight.back().first;
}

// x^n for a small whole n >= 0, by squaring (glibc's pow was a tenth of the
// refiner's time at the default power 4).
double IntegerPower(double x, int n) {
  double result = 1.0;
  for (; n > 0; n >>= 1, x *= x)
    if (n & 1) result *= x;
  return result;
}

// The weight factor of each of `views` satellite views in one sample: 0 for
// a view the sample leaves out, else drawn from [1 - jitter, 1 + jitter].
// Seeded per view and sample, so reruns and resumes draw the same.
std::vector<float> SampleFactors(const ReprojectOptions& o, const RefineRequest& request, std::size_t view, int sample,
                                 int views) {
  std::mt19937_64 rng(SampleSeed(request, view, sample));
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<float> factor(views, 0.0f);
  bool any = false;
  for (int s = 0; s < views; ++s) {
    const bool keep = unit(rng) < o.keep_probability;
    const double jitter = 1.0 + o.weight_jitter * (2.0 * unit(rng) - 1.0);
    factor[s] = keep ? static_cast<float>(jitter) : 0.0f;
    any = any || keep;
  }
  if (!any) factor[rng() % views] = 1.0f;
  return factor;
}

}  // namespace

void ReprojectOptions::Check() const { CheckOptionRanges(*this, "idu", "reproject"); }

ReprojectRefiner::ReprojectRefiner(const std::vector<TrainView>& satellite, ReprojectOptions options, RasterOptions raster,
                                   const SurfaceDepthPrior* surface)
    : satellite_(satellite), options_(std::move(options)), raster_(raster), surface_(surface) {
  options_.Check();
  if (satellite_.empty()) throw Error("idu", "refiner", "reproject needs satellite views");
  for (const TrainView& s : satellite_) satellite_centres_.push_back(s.camera.Centre());
}

namespace {

// What a pixel's votes are drawn from: the satellite views, their visible
// depth, their camera centres and the refiner's options.
struct VoteSources {
  const std::vector<TrainView>& satellite;
  const std::vector<SatelliteDepth>& depth;
  const std::vector<Eigen::Vector3d>& centres;
  const ReprojectOptions& options;
};

// One vote per satellite view that sees world point X (not hidden there by a
// nearer surface), weighted by how close its direction is to the orbit eye's.
void CollectVotes(const VoteSources& src, const Eigen::Vector3d& X, const Eigen::Vector3d& eye,
                  std::vector<Vote>* votes) {
  const double power = src.options.angle_weight_power;
  const bool integer_power = power == std::floor(power) && power <= 16;
  const Eigen::Vector3d to_orbit = (eye - X).normalized();
  votes->clear();
  for (int s = 0; s < static_cast<int>(src.satellite.size()); ++s) {
    const TrainView& sv = src.satellite[s];
    const Eigen::Vector2d uv = sv.camera.Project(X);
    if (!(uv.x() >= 0 && uv.y() >= 0 && uv.x() <= sv.camera.width_px - 1 && uv.y() <= sv.camera.height_px - 1))
      continue;
    const std::size_t q = static_cast<std::size_t>(std::lround(uv.y())) * sv.camera.width_px + std::lround(uv.x());
    if (!sv.valid.empty() && !sv.valid[q]) continue;
    const float seen = src.depth[s].depth[q];
    if (!std::isfinite(seen)) continue;
    const double here = sv.camera.Depth(X) - src.depth[s].reference_m;
    if (std::abs(here - seen) > src.options.visibility_tolerance_m) continue;  // hidden from this view
    const double cosine = std::max(0.0, to_orbit.dot((src.centres[s] - X).normalized()));
    const double weight = integer_power ? IntegerPower(cosine, static_cast<int>(power)) : std::pow(cosine, power);
    votes->push_back({s, static_cast<float>(weight) + 1e-6f, Bilinear(sv, uv.x(), uv.y())});
  }
}

// Each sample's colour of one pixel: the weighted median of the votes of the
// views that sample keeps (all votes when it keeps none of them).
void SampleColours(const std::vector<Vote>& votes, const std::vector<std::vector<float>>& factors, int y, int x,
                   std::vector<cv::Mat>* images, std::vector<std::pair<float, float>>* channel) {
  for (std::size_t k = 0; k < factors.size(); ++k) {
    const std::vector<float>& factor = factors[k];
    bool subset = false;
    for (const Vote& v : votes) subset = subset || factor[v.view] > 0;
    cv::Vec3f& px = (*images)[k].at<cv::Vec3f>(y, x);
    for (int c = 0; c < 3; ++c) {
      channel->clear();
      for (const Vote& v : votes) {
        const float w = subset ? v.weight * factor[v.view] : v.weight;
        if (w > 0) channel->emplace_back(v.colour[c], w);
      }
      px[c] = WeightedMedian(*channel);
    }
  }
}

// Pixels no satellite view sees are inpainted (or keep the render), the
// image smoothed, and returned as interleaved RGB in [0, 1].
std::vector<float> FinishSample(const ReprojectOptions& o, const cv::Mat& unseen, cv::Mat image) {
  if (o.inpaint != Inpaint::kRender && cv::countNonZero(unseen) > 0) {
    cv::Mat bytes, filled;
    image.convertTo(bytes, CV_8UC3, 255.0);
    cv::inpaint(bytes, unseen, filled, o.inpaint_radius_px,
                o.inpaint == Inpaint::kNavierStokes ? cv::INPAINT_NS : cv::INPAINT_TELEA);
    cv::Mat filled_f;
    filled.convertTo(filled_f, CV_32FC3, 1.0 / 255.0);
    filled_f.copyTo(image, unseen);
  }
  if (o.smooth_diameter_px > 0) {
    cv::Mat smooth;
    cv::bilateralFilter(image, smooth, o.smooth_diameter_px, o.smooth_sigma_colour, o.smooth_sigma_space_px);
    image = smooth;
  }
  const int W = image.cols, H = image.rows;
  std::vector<float> rgb(3 * static_cast<std::size_t>(W) * H);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < 3; ++c)
        rgb[3 * (static_cast<std::size_t>(y) * W + x) + c] = std::clamp(image.at<cv::Vec3f>(y, x)[c], 0.0f, 1.0f);
  return rgb;
}

// The samples of one orbit view (number `vi` of the request).
RefinedSamples RefineView(const VoteSources& src, const RefineInput& in, std::size_t vi,
                          const RefineRequest& request) {
  const PinholeCamera& cam = in.camera;
  const int W = cam.width_px, H = cam.height_px;
  const std::size_t n = static_cast<std::size_t>(W) * H;
  if (in.rgb.size() != 3 * n || in.depth_m.size() != n) throw Error("idu", in.name, "render size does not match its camera");
  // Each sample keeps a random subset of the satellite views with jittered
  // weights (drawn before the pixels, so they do not depend on threads).
  const int S = static_cast<int>(src.satellite.size());
  std::vector<std::vector<float>> factors(request.samples);
  for (int k = 0; k < request.samples; ++k) factors[k] = SampleFactors(src.options, request, vi, k, S);
  std::vector<cv::Mat> images(request.samples);
  for (cv::Mat& image : images) image.create(H, W, CV_32FC3);
  cv::Mat unseen = cv::Mat::zeros(H, W, CV_8U);
  const PixelToWorld to_world(cam);
  const Eigen::Vector3d eye = cam.Centre();
  tbb::parallel_for(tbb::blocked_range<int>(0, H), [&](const tbb::blocked_range<int>& rows) {
    std::vector<Vote> votes;  // the pixel's votes, one per satellite view that sees its point
    votes.reserve(S);
    std::vector<std::pair<float, float>> channel;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < W; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * W + x;
        for (cv::Mat& image : images) {
          cv::Vec3f& px = image.at<cv::Vec3f>(y, x);
          for (int c = 0; c < 3; ++c) px[c] = in.rgb[3 * p + c];
        }
        const double depth = in.depth_m[p];
        if (!std::isfinite(depth)) continue;  // no surface: the render stays (masked in training)
        CollectVotes(src, to_world(x, y, depth), eye, &votes);
        if (votes.empty()) {
          unseen.at<std::uint8_t>(y, x) = 255;
          continue;
        }
        SampleColours(votes, factors, y, x, &images, &channel);
      }
    }
  });
  RefinedSamples out;
  for (cv::Mat& image : images) out.push_back(FinishSample(src.options, unseen, image));
  return out;
}

}  // namespace

std::vector<RefinedSamples> ReprojectRefiner::Refine(const GaussianCloud& scene, const std::vector<RefineInput>& views,
                                                     const RefineRequest& request, Progress& progress) {
  std::vector<SatelliteDepth> sat_depth;
  for (const TrainView& s : satellite_) sat_depth.push_back(RenderSatelliteDepth(scene, s, raster_));
  if (surface_) {
    // The height field decides visibility where it has an answer.
    const bool first = surface_in_satellite_.empty();
    for (std::size_t s = 0; s < satellite_.size(); ++s) {
      // Relative to the render's reference depth (the camera depth of the
      // frame origin): satellite depths of ~6e5 m keep centimetres only so.
      const PinholeCamera& cam = satellite_[s].camera;
      if (first) surface_in_satellite_.push_back(surface_->DepthRelativeTo(cam, cam.cam_from_world_translation.z()));
      const DepthMap& m = surface_in_satellite_[s];
      for (std::size_t q = 0; q < m.depth.size(); ++q)
        if (m.valid[q]) sat_depth[s].depth[q] = m.depth[q];
    }
  }
  const VoteSources sources{satellite_, sat_depth, satellite_centres_, options_};
  std::vector<RefinedSamples> out(views.size());
  progress.Begin("idu refine (reproject)", views.size());
  for (std::size_t vi = 0; vi < views.size(); ++vi) {
    out[vi] = RefineView(sources, views[vi], vi, request);
    progress.Advance(vi + 1, views[vi].name);
  }
  progress.End();
  return out;
}

CommandRefiner::CommandRefiner(std::string command, std::string work_dir)
    : command_(std::move(command)), work_dir_(std::move(work_dir)) {
  if (command_.empty()) throw Error("idu", "refiner", "cmd: needs a command");
}

std::vector<RefinedSamples> CommandRefiner::Refine(const GaussianCloud& /*scene*/, const std::vector<RefineInput>& views,
                                                   const RefineRequest& request, Progress& progress) {
  using json = nlohmann::json;
  const fs::path base = fs::path(work_dir_) / ("episode_" + std::to_string(request.episode));
  const fs::path in_dir = base / "in", out_dir = base / "out";
  fs::remove_all(in_dir);
  fs::remove_all(out_dir);
  fs::create_directories(in_dir);
  fs::create_directories(out_dir);
  json list = json::array();
  for (std::size_t v = 0; v < views.size(); ++v) {
    const RefineInput& in = views[v];
    const int W = in.camera.width_px, H = in.camera.height_px;
    WriteUnitPng((in_dir / (in.name + ".png")).string(), W, H, 3, in.rgb, PngCompression::kFast);
    json seeds = json::array();
    for (int k = 0; k < request.samples; ++k) seeds.push_back(SampleSeed(request, v, k));
    list.push_back({{"name", in.name}, {"file", in.name + ".png"}, {"width_px", W}, {"height_px", H},
                    {"elevation_deg", in.elevation_deg}, {"azimuth_deg", in.azimuth_deg}, {"seeds", seeds},
                    {"outputs", [&] {
                       json names = json::array();
                       for (int k = 0; k < request.samples; ++k) names.push_back(in.name + "_s" + std::to_string(k) + ".png");
                       return names;
                     }()}});
  }
  const json doc = {{"schema", "skyfall.refine_request/1"},
                    {"episode", request.episode},
                    {"samples", request.samples},
                    {"seed", request.seed},
                    {"source_prompt", request.source_prompt},
                    {"target_prompt", request.target_prompt},
                    {"n_min", request.n_min},
                    {"n_max", request.n_max},
                    {"n_avg", request.n_avg},
                    {"steps", request.steps},
                    {"source_guidance_scale", request.source_guidance_scale},
                    {"target_guidance_scale", request.target_guidance_scale},
                    {"views", list}};
  WriteFileAtomic((in_dir / "request.json").string(), doc.dump(2) + "\n");
  progress.Begin("idu refine (" + command_ + ")", 0);
  const std::string cmd = command_ + " '" + in_dir.string() + "' '" + out_dir.string() + "'";
  const int status = std::system(cmd.c_str());
  if (status != 0) {
    throw Error("idu", command_, "refiner command failed (status " + std::to_string(status) + ") on " + in_dir.string());
  }
  std::vector<RefinedSamples> out(views.size());
  for (std::size_t v = 0; v < views.size(); ++v) {
    const RefineInput& in = views[v];
    const int W = in.camera.width_px, H = in.camera.height_px;
    for (int k = 0; k < request.samples; ++k) {
      const fs::path file = out_dir / (in.name + "_s" + std::to_string(k) + ".png");
      if (!fs::exists(file)) throw Error("idu", file.string(), "the refiner did not write this sample");
      const FloatImage img = ReadFloatImage(file.string());
      if (img.width_px != W || img.height_px != H)
        throw Error("idu", file.string(), "is " + std::to_string(img.width_px) + "x" + std::to_string(img.height_px) +
                                              ", the render is " + std::to_string(W) + "x" + std::to_string(H));
      if (img.bands != 1 && img.bands != 3 && img.bands != 4)
        throw Error("idu", file.string(), "has " + std::to_string(img.bands) + " bands; expected 1 (grey), 3 (RGB) or 4 (RGBA)");
      std::vector<float> rgb(3 * static_cast<std::size_t>(W) * H);
      for (std::size_t p = 0; p < rgb.size() / 3; ++p)
        for (int c = 0; c < 3; ++c)
          rgb[3 * p + c] = std::clamp(img.values[img.bands * p + (img.bands == 1 ? 0 : c)] / 255.0f, 0.0f, 1.0f);
      out[v].push_back(std::move(rgb));
    }
  }
  progress.End();
  return out;
}

std::unique_ptr<Refiner> MakeRefiner(const std::string& spec, const std::vector<TrainView>& satellite,
                                     const ReprojectOptions& reproject, const std::string& work_dir,
                                     const std::string& field, const SurfaceDepthPrior* surface) {
  if (spec == "reproject") return std::make_unique<ReprojectRefiner>(satellite, reproject, RasterOptions{}, surface);
  if (spec.rfind("cmd:", 0) == 0) return std::make_unique<CommandRefiner>(spec.substr(4), work_dir);
  throw Error("idu", field, "'" + spec + "' is not 'reproject' or 'cmd:COMMAND'");
}

}  // namespace skyfall
