#include "pipeline/view_masks.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "core/pinhole.h"
#include "splat/dataset.h"
#include "splat/depth_prior.h"

namespace skyfall {
namespace {

constexpr float kCoveredAlpha = 0.5f;  // a pixel sees the tile's surface

// The ground point a pixel sees through the cover, and whether other views
// see it too.
struct CoverGeometry {
  const RenderOutput<float>& cover;
  const PinholeCamera& camera;

  bool Covered(std::size_t p) const { return cover.alpha[p] >= kCoveredAlpha; }
  Eigen::Vector3d GroundPoint(const PixelToWorld& to_world, int x, int y, std::size_t p) const {
    return to_world(x, y, static_cast<double>(cover.depth[p]) + cover.reference_depth_m);
  }
  // The pixel (row-major index) at which this view sees `world` unhidden;
  // -1 when it falls outside, on no surface, or behind another surface.
  long SeenAt(const Eigen::Vector3d& world, double tolerance_m) const {
    const Eigen::Vector2d uv = camera.Project(world);
    const long x = std::lround(uv.x()), y = std::lround(uv.y());
    if (x < 0 || y < 0 || x >= cover.width_px || y >= cover.height_px) return -1;
    const std::size_t p = static_cast<std::size_t>(y) * cover.width_px + x;
    if (!Covered(p)) return -1;
    const double surface_depth = static_cast<double>(cover.depth[p]) + cover.reference_depth_m;
    return std::abs(camera.Depth(world) - surface_depth) <= tolerance_m ? static_cast<long>(p) : -1;
  }
};

using Rgb = std::array<float, 3>;

Rgb PixelRgb(const TrainView& v, std::size_t p) { return {v.rgb[3 * p], v.rgb[3 * p + 1], v.rgb[3 * p + 2]}; }

bool HasData(const TrainView& v, std::size_t p) { return v.valid.empty() || v.valid[p]; }

// The q-quantile of `values` (reordered), nearest rank.
float Quantile(std::vector<float>& values, double q) {
  const std::size_t k = std::min(values.size() - 1, static_cast<std::size_t>(q * static_cast<double>(values.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<long>(k), values.end());
  return values[k];
}

// Calls fn(x, y, p, others) for each pixel of view j with data on the top
// surface (`top`: roofs and ground, not walls) that at least
// min_other_views other training views see, `others`
// holding their colours there divided by their gains; with call_unjudged,
// fn(x, y, p, {}) for the pixels on the surface that too few others see.
template <class Fn>
void ForEachJudgedPixel(std::size_t j, const std::vector<CoverGeometry>& geometry, const SurfaceDepthPrior& top,
                        const std::vector<TrainView>& views, const std::vector<std::size_t>& train,
                        const std::vector<Rgb>& gains, const CloudMaskOptions& o, int stride, Fn&& fn,
                        bool call_unjudged = false) {
  const CoverGeometry& g = geometry[j];
  const PixelToWorld to_world(g.camera);
  std::vector<Rgb> others;
  for (int y = 0; y < g.cover.height_px; y += stride) {
    for (int x = 0; x < g.cover.width_px; x += stride) {
      const std::size_t p = static_cast<std::size_t>(y) * g.cover.width_px + x;
      if (!HasData(views[j], p) || !g.Covered(p)) continue;
      const Eigen::Vector3d ground = g.GroundPoint(to_world, x, y, p);
      others.clear();
      // Walls are left unjudged: a wall the sun lights on one date and not
      // on the others is brighter there than anywhere, and white walls are
      // whitish (a tower's facades in an oblique view).
      const double top_m = top.HeightAt(ground.x(), ground.y());
      const bool on_top = std::abs(ground.z() - top_m) <= o.surface_tolerance_m;
      for (std::size_t k : train) {
        if (!on_top) break;
        if (k == j) continue;
        const long q = geometry[k].SeenAt(ground, o.surface_tolerance_m);
        if (q < 0 || !HasData(views[k], static_cast<std::size_t>(q))) continue;
        const Rgb c = PixelRgb(views[k], static_cast<std::size_t>(q));
        others.push_back({c[0] / gains[k][0], c[1] / gains[k][1], c[2] / gains[k][2]});
      }
      if (static_cast<int>(others.size()) >= o.min_other_views) {
        fn(x, y, p, others);
      } else if (call_unjudged) {
        others.clear();
        fn(x, y, p, others);
      }
    }
  }
}

// Per channel, the factor by which view j's colours exceed the median of the
// other views at the same ground points (the median over its pixels, so
// that clouds covering less than half of it do not move it).
Rgb ViewGain(std::size_t j, const std::vector<CoverGeometry>& geometry, const SurfaceDepthPrior& top,
             const std::vector<TrainView>& views, const std::vector<std::size_t>& train, const CloudMaskOptions& o) {
  constexpr int kStride = 3;            // a ninth of the pixels is plenty for a median
  constexpr float kDarkest = 0.02f;     // ratios of near-black pixels are noise
  constexpr float kMinGain = 0.2f, kMaxGain = 5.0f;
  const std::vector<Rgb> unit(views.size(), Rgb{1, 1, 1});
  std::array<std::vector<float>, 3> ratios;
  std::vector<float> channel;
  ForEachJudgedPixel(j, geometry, top, views, train, unit, o, kStride,
                     [&](int, int, std::size_t p, const std::vector<Rgb>& others) {
                       const Rgb c = PixelRgb(views[j], p);
                       for (int ch = 0; ch < 3; ++ch) {
                         channel.clear();
                         for (const Rgb& v : others) channel.push_back(v[ch]);
                         const float median = Quantile(channel, 0.5);
                         if (median > kDarkest) ratios[ch].push_back(c[ch] / median);
                       }
                     });
  Rgb gain{1, 1, 1};
  for (int ch = 0; ch < 3; ++ch)
    if (!ratios[ch].empty()) gain[ch] = std::clamp(Quantile(ratios[ch], 0.5), kMinGain, kMaxGain);
  return gain;
}

constexpr std::uint8_t kCloudy = 255, kUnjudged = 128;

// kCloudy where view j's pixel is cloudy (before the area rule and
// growing), kUnjudged where too few other views see its ground point (a
// wall that faces this view alone, say).
cv::Mat CloudyPixels(std::size_t j, const std::vector<CoverGeometry>& geometry, const SurfaceDepthPrior& top,
                     const std::vector<TrainView>& views, const std::vector<std::size_t>& train,
                     const std::vector<Rgb>& gains, const CloudMaskOptions& o) {
  cv::Mat cloudy = cv::Mat::zeros(geometry[j].cover.height_px, geometry[j].cover.width_px, CV_8U);
  std::vector<float> channel;
  auto judge = [&](int x, int y, std::size_t p, const std::vector<Rgb>& others) {
    if (others.empty()) {
      cloudy.at<std::uint8_t>(y, x) = kUnjudged;
      return;
    }
    // In this view's own units: a cloud is white (or saturated) as imaged,
    // whatever gain the date's light and processing gave the ground.
    const Rgb c = PixelRgb(views[j], p);
    Rgb excess{};
    for (int ch = 0; ch < 3; ++ch) {
      channel.clear();
      for (const Rgb& v : others) channel.push_back(v[ch]);
      excess[ch] = c[ch] - gains[j][ch] * Quantile(channel, 0.75);
    }
    const float mean = (excess[0] + excess[1] + excess[2]) / 3.0f;
    const float brightest = std::max({c[0], c[1], c[2]});
    const float chroma = brightest > 0 ? (brightest - std::min({c[0], c[1], c[2]})) / brightest : 1.0f;
    if (mean >= o.min_brightening && std::min({excess[0], excess[1], excess[2]}) > 0 && chroma <= o.max_chroma)
      cloudy.at<std::uint8_t>(y, x) = kCloudy;
  };
  ForEachJudgedPixel(j, geometry, top, views, train, gains, o, 1, judge, /*call_unjudged=*/true);
  return cloudy;
}

cv::Mat Disc(int radius_px) {
  return cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius_px + 1, 2 * radius_px + 1));
}

// Unjudged pixels this close to a cloud join it: a cloud is one blob, and
// what it hides there no other view can vouch for (a wall facing this view
// alone shows as a band of about a building's height times the tangent of
// the view's zenith angle; half of a 10 m band is within reach from either side).
constexpr double kUnjudgedReachM = 5.0;

// Drops cloudy patches under min_area_m2, adds the unjudged pixels near the
// rest, and grows the result by grow_m.
cv::Mat CloudMask(const cv::Mat& judged, double gsd_m, const CloudMaskOptions& o) {
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(judged == kCloudy, labels, stats, centroids, 8, CV_32S);
  const double min_pixels = o.min_area_m2 / (gsd_m * gsd_m);
  cv::Mat kept = cv::Mat::zeros(judged.size(), CV_8U);
  for (int label = 1; label < n; ++label)
    if (stats.at<int>(label, cv::CC_STAT_AREA) >= min_pixels) kept.setTo(255, labels == label);
  if (cv::countNonZero(kept) == 0) return kept;
  const int reach_px = static_cast<int>(std::ceil(kUnjudgedReachM / gsd_m));
  cv::Mat near_cloud;
  cv::dilate(kept, near_cloud, Disc(reach_px));
  kept |= near_cloud & (judged == kUnjudged);
  const int grow_px = static_cast<int>(std::ceil(o.grow_m / gsd_m));
  if (grow_px > 0) {
    cv::dilate(kept, kept, Disc(grow_px));
  }
  return kept;
}

}  // namespace

void CloudMaskOptions::Check() const { CheckOptionRanges(*this, "train", "cloud_mask"); }

std::vector<RenderOutput<float>> RenderDenseCover(const DenseCells& cells, double spacing_m,
                                                  const RasterOptions& raster, const std::vector<TrainView>& views) {
  if (cells.points.empty()) return {};
  std::vector<Eigen::Vector3f> points, colours, walls, wall_colours;
  ThinToGrid(spacing_m, cells.points, cells.colours, {}, {}, &points, &colours);
  std::vector<int> wall_normals;
  FacadePoints(cells.points, cells.colours, cells.cell_m, spacing_m, spacing_m, &walls, &wall_colours, &wall_normals);
  points.insert(points.end(), walls.begin(), walls.end());
  colours.insert(colours.end(), wall_colours.begin(), wall_colours.end());
  // Blobs as wide as the spacing, nearly opaque: a closed surface wherever
  // the heights reach, fading within about a spacing beyond their edge.
  GaussianCloud cover = InitializeFromPoints(points, colours, spacing_m, 1);
  constexpr float kOpaqueLogit = 4.6f;  // opacity 0.99
  for (float& logit : cover.opacity_logits) logit = kOpaqueLogit;
  std::vector<RenderOutput<float>> renders;
  renders.reserve(views.size());
  for (const TrainView& v : views) {
    renders.push_back(RenderGaussians(cover, v.camera, raster));
    renders.back().state = {};  // the gradients' bookkeeping is not needed
  }
  return renders;
}

double MaskBeyondReconstruction(const std::vector<RenderOutput<float>>& covers, std::vector<TrainView>* views) {
  if (covers.empty()) return 0.0;
  std::size_t with_data = 0, masked = 0;
  for (std::size_t j = 0; j < views->size(); ++j) {
    TrainView& v = (*views)[j];
    for (std::size_t p = 0; p < v.valid.size(); ++p) {
      if (!v.valid[p]) continue;
      ++with_data;
      if (covers[j].alpha[p] < kCoveredAlpha) {
        v.valid[p] = 0;
        ++masked;
      }
    }
  }
  return with_data ? static_cast<double>(masked) / static_cast<double>(with_data) : 0.0;
}

double MaskBeyondReconstruction(const DenseCells& cells, double spacing_m, const RasterOptions& raster,
                                std::vector<TrainView>* views) {
  return MaskBeyondReconstruction(RenderDenseCover(cells, spacing_m, raster, *views), views);
}

std::vector<double> MaskClouds(const DenseCells& cells, const std::vector<RenderOutput<float>>& covers,
                               const CloudMaskOptions& o, std::vector<TrainView>* views_io) {
  o.Check();
  std::vector<TrainView>& views = *views_io;
  std::vector<double> masked_fraction(views.size(), 0.0);
  std::vector<std::size_t> train;
  for (std::size_t j = 0; j < views.size(); ++j)
    if (!views[j].held_out) train.push_back(j);
  if (!o.enabled || cells.points.empty() || covers.size() != views.size() ||
      static_cast<int>(train.size()) < o.min_other_views + 1)
    return masked_fraction;
  const SurfaceDepthPrior top(cells.points, cells.cell_m);
  std::vector<CoverGeometry> geometry;
  for (std::size_t j = 0; j < views.size(); ++j) geometry.push_back({covers[j], views[j].camera});
  std::vector<Rgb> gains(views.size(), Rgb{1, 1, 1});
  tbb::parallel_for(std::size_t{0}, train.size(),
                    [&](std::size_t i) { gains[train[i]] = ViewGain(train[i], geometry, top, views, train, o); });
  // Judged against the unmasked colours of every view, then applied.
  std::vector<cv::Mat> masks(views.size());
  tbb::parallel_for(std::size_t{0}, train.size(), [&](std::size_t i) {
    const std::size_t j = train[i];
    const double gsd_m = views[j].camera.PixelFootprintM(Eigen::Vector3d::Zero());
    masks[j] = CloudMask(CloudyPixels(j, geometry, top, views, train, gains, o), gsd_m, o);
  });
  for (std::size_t j : train) {
    TrainView& v = views[j];
    if (v.valid.empty()) v.valid.assign(v.rgb.size() / 3, 1);
    std::size_t with_data = 0, masked = 0;
    for (std::size_t p = 0; p < v.valid.size(); ++p) {
      if (!v.valid[p]) continue;
      ++with_data;
      if (masks[j].data[p]) {
        v.valid[p] = 0;
        ++masked;
      }
    }
    masked_fraction[j] = with_data ? static_cast<double>(masked) / static_cast<double>(with_data) : 0.0;
  }
  return masked_fraction;
}

}  // namespace skyfall
