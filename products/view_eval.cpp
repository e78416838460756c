#include "products/view_eval.h"

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "catalogs/tile_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "dense/dense_cells.h"
#include "splat/dataset.h"
#include "splat/depth_prior.h"
#include "splat/losses.h"
#include "synthesis/orbit.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::vector<float> ReadRgb01(const std::string& path, int* w, int* h) {
  const FloatImage img = ReadFloatImage(path);
  if (img.bands < 3) throw Error("compare", path, "is not an RGB image");
  *w = img.width_px;
  *h = img.height_px;
  std::vector<float> rgb(3 * static_cast<std::size_t>(img.width_px) * img.height_px);
  for (std::size_t p = 0; p < rgb.size() / 3; ++p)
    for (int c = 0; c < 3; ++c) rgb[3 * p + c] = img.values[img.bands * p + c] / 255.0f;
  return rgb;
}

}  // namespace

int WriteEvalOrbitCameras(const std::string& tile_dir, const EvalOrbitOptions& o, const std::string& out_json) {
  const TileSpec spec = ReadTileSpec((fs::path(tile_dir) / "tile.json").string());
  const GroundBox box = spec.ReconstructedCore();
  const fs::path dense = fs::path(tile_dir) / "sfm" / "dense.ply";
  if (!fs::exists(dense)) throw Error("compare", dense.string(), "missing: the tile has no dense heights to look at");
  const DenseCells cells = ReadDenseCells(dense.string());
  const SurfaceDepthPrior surface(cells.points, cells.cell_m);
  std::vector<OrbitView> views;
  const double side = std::max(box.Width(), box.Height());
  int point = 0;
  for (const double f : {1.0 / 3.0, 2.0 / 3.0}) {
    const double e = box.min_m.x() + f * box.Width(), n = box.min_m.y() + f * box.Height();
    const double h = surface.HeightAt(e, n);
    const Eigen::Vector3d look_at(e, n, std::isfinite(h) ? h : 0.0);
    for (double elevation : o.elevations_deg) {
      // Rings start half a step (point 0) or one and a half steps (point 1) of
      // 180 deg / views round, away from the training rings' golden-ratio phases.
      const double azimuth0 = (point + 0.5) * 180.0 / std::max(1, o.views_per_elevation);
      for (OrbitView& v : OrbitRing(look_at, std::max(o.min_radius_m, o.radius_per_core * side), elevation, o.views_per_elevation, azimuth0,
                                    o.fov_deg, o.width_px, o.height_px)) {
        v.point = point;
        char name[64];
        std::snprintf(name, sizeof(name), "el%02d_p%d_v%d", static_cast<int>(std::lround(elevation)), point, v.view);
        v.name = name;
        views.push_back(v);
      }
    }
    ++point;
  }
  WriteFileAtomic(out_json, OrbitCamerasJson(views, spec.enu_origin));
  return static_cast<int>(views.size());
}

double MaskedSsim(const std::vector<float>& a, const std::vector<float>& b, const std::vector<std::uint8_t>& mask,
                  int w, int h) {
  constexpr double kC1 = 0.01 * 0.01, kC2 = 0.03 * 0.03;  // (k L)^2 with L = 1
  double sum = 0;
  std::size_t n = 0;
  for (int c = 0; c < 3; ++c) {
    cv::Mat x(h, w, CV_32F), y(h, w, CV_32F);
    for (int r = 0; r < h; ++r)
      for (int k = 0; k < w; ++k) {
        x.at<float>(r, k) = a[3 * (static_cast<std::size_t>(r) * w + k) + c];
        y.at<float>(r, k) = b[3 * (static_cast<std::size_t>(r) * w + k) + c];
      }
    auto blur = [](const cv::Mat& m) {
      cv::Mat out;
      cv::GaussianBlur(m, out, cv::Size(11, 11), 1.5, 1.5, cv::BORDER_REFLECT);
      return out;
    };
    const cv::Mat mx = blur(x), my = blur(y);
    const cv::Mat sxx = blur(x.mul(x)) - mx.mul(mx), syy = blur(y.mul(y)) - my.mul(my), sxy = blur(x.mul(y)) - mx.mul(my);
    for (int r = 0; r < h; ++r)
      for (int k = 0; k < w; ++k) {
        if (!mask[static_cast<std::size_t>(r) * w + k]) continue;
        const double ux = mx.at<float>(r, k), uy = my.at<float>(r, k);
        const double s = ((2 * ux * uy + kC1) * (2 * sxy.at<float>(r, k) + kC2)) /
                         ((ux * ux + uy * uy + kC1) * (sxx.at<float>(r, k) + syy.at<float>(r, k) + kC2));
        sum += s;
        ++n;
      }
  }
  return n ? sum / n : NAN;
}

namespace {

// The first view of each elevation's images: its renders, then its truth.
using GalleryRows = std::map<double, std::vector<std::vector<float>>>;

// One view's scores against its truth image and mask; its images (renders,
// then the truth) go to `row`, their size to w x h.
ViewScores ScoreView(const json& image, const std::string& truth_dir, const std::vector<std::string>& render_dirs,
                     std::vector<std::vector<float>>* row, int* w, int* h) {
  ViewScores s;
  s.name = image.at("name").get<std::string>();
  s.elevation_deg = std::round(10.0 * image.value("elevation_deg", 0.0)) / 10.0;
  const std::vector<float> truth = ReadRgb01((fs::path(truth_dir) / (s.name + ".png")).string(), w, h);
  const FloatBand mask_band = ReadFloatBand((fs::path(truth_dir) / (s.name + "_mask.png")).string());
  std::vector<std::uint8_t> mask(mask_band.values.size());
  for (std::size_t p = 0; p < mask.size(); ++p) mask[p] = mask_band.values[p] > 127;
  for (const std::string& dir : render_dirs) {
    int rw = 0, rh = 0;
    const fs::path path = fs::path(dir) / (s.name + "_rgb.png");
    const std::vector<float> render = ReadRgb01(path.string(), &rw, &rh);
    if (rw != *w || rh != *h) throw Error("compare", path.string(), "differs in size from its truth image");
    s.psnr_db.push_back(MaskedPsnr(render, truth, mask));
    s.ssim.push_back(MaskedSsim(render, truth, mask, *w, *h));
    row->push_back(render);
  }
  row->push_back(truth);
  return s;
}

// Per elevation, the mean PSNR and SSIM of each render directory over the
// views where it is finite (NaN where none is).
void AveragePerElevation(ViewComparison* result, std::size_t renders) {
  std::map<double, std::vector<int>> count;
  for (const ViewScores& s : result->views) {
    auto& psnr = result->psnr_db[s.elevation_deg];
    auto& ssim = result->ssim[s.elevation_deg];
    auto& k = count[s.elevation_deg];
    psnr.resize(renders, 0.0);
    ssim.resize(renders, 0.0);
    k.resize(renders, 0);
    for (std::size_t d = 0; d < renders; ++d) {
      if (!std::isfinite(s.psnr_db[d])) continue;
      psnr[d] += s.psnr_db[d];
      ssim[d] += s.ssim[d];
      ++k[d];
    }
  }
  for (auto& [el, v] : result->psnr_db)
    for (std::size_t d = 0; d < v.size(); ++d) {
      v[d] = count[el][d] ? v[d] / count[el][d] : NAN;
      result->ssim[el][d] = count[el][d] ? result->ssim[el][d] / count[el][d] : NAN;
    }
}

// The gallery: rows from high to low elevation, each view's images of w x h side by side.
void WriteGallery(const GalleryRows& rows_by_elevation, int cols, int W, int H, const std::string& path) {
  const int rows = static_cast<int>(rows_by_elevation.size());
  const int GW = cols * W, GH = rows * H;
  std::vector<std::uint8_t> gallery(3 * static_cast<std::size_t>(GW) * GH, 0);
  int r = 0;
  for (auto it = rows_by_elevation.rbegin(); it != rows_by_elevation.rend(); ++it, ++r) {
    for (int c = 0; c < cols; ++c) {
      const std::vector<float>& img = it->second[c];
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          for (int ch = 0; ch < 3; ++ch)
            gallery[3 * ((static_cast<std::size_t>(r) * H + y) * GW + c * W + x) + ch] = static_cast<std::uint8_t>(
                std::clamp(img[3 * (static_cast<std::size_t>(y) * W + x) + ch], 0.0f, 1.0f) * 255.0f + 0.5f);
    }
  }
  WriteBytePng(path, GW, GH, 3, gallery.data());
}

}  // namespace

ViewComparison CompareViews(const std::string& cameras_json, const std::string& truth_dir,
                            const std::vector<std::string>& render_dirs, const std::string& out_dir, Progress& progress) {
  const json cams = json::parse(ReadTextFile(cameras_json));
  ViewComparison result;
  GalleryRows row_images;
  int W = 0, H = 0;
  progress.Begin("compare views", cams.at("images").size());
  std::size_t done = 0;
  for (const json& im : cams.at("images")) {
    std::vector<std::vector<float>> row;
    int w = 0, h = 0;
    ViewScores s = ScoreView(im, truth_dir, render_dirs, &row, &w, &h);
    if (!row_images.count(s.elevation_deg)) {
      row_images[s.elevation_deg] = std::move(row);
      W = w;
      H = h;
    }
    result.views.push_back(std::move(s));
    progress.Advance(++done, result.views.back().name);
  }
  progress.End();
  AveragePerElevation(&result, render_dirs.size());
  fs::create_directories(out_dir);
  json views = json::array();
  for (const ViewScores& s : result.views) views.push_back({{"name", s.name}, {"elevation_deg", s.elevation_deg},
                                                            {"psnr_db", s.psnr_db}, {"ssim", s.ssim}});
  json per = json::array();
  for (const auto& [el, v] : result.psnr_db) per.push_back({{"elevation_deg", el}, {"psnr_db", v}, {"ssim", result.ssim[el]}});
  WriteFileAtomic((fs::path(out_dir) / "compare.json").string(),
                  json({{"renders", render_dirs}, {"truth", truth_dir}, {"per_elevation", per}, {"views", views}}).dump(2) + "\n");
  if (!row_images.empty())
    WriteGallery(row_images, static_cast<int>(render_dirs.size()) + 1, W, H, (fs::path(out_dir) / "gallery.png").string());
  return result;
}

}  // namespace skyfall
