#include "sfm/export.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"
#include "catalogs/aoi_catalog.h"
#include "ingest/radiometry.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

json Matrix(const Eigen::Matrix3d& m) {
  return {{m(0, 0), m(0, 1), m(0, 2)}, {m(1, 0), m(1, 1), m(1, 2)}, {m(2, 0), m(2, 1), m(2, 2)}};
}
json Vector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

std::string CamerasJson(const SfmResult& r, const AoiCatalog& c) {
  json images = json::array();
  for (const SfmImage& im : r.images) {
    const PinholeCamera& cam = im.camera;
    const bool held_out = std::find(c.test_images.begin(), c.test_images.end(), im.name) != c.test_images.end();
    images.push_back({{"name", im.name},
                      {"source_image", im.path},
                      {"used", im.used},
                      {"split", held_out ? "test" : "train"},
                      {"status", im.status},
                      {"width_px", cam.width_px},
                      {"height_px", cam.height_px},
                      {"acquisition_time", im.acquisition_time},
                      {"radiometry", im.radiometry.Measured() ? json::parse(RadiometryJson(im.radiometry)) : json()},
                      {"K", Matrix(cam.K())},
                      {"R", Matrix(cam.cam_from_world_rotation)},
                      {"t", Vector(cam.cam_from_world_translation)},
                      {"centre_enu_m", Vector(cam.Centre())},
                      {"pinhole_max_error_px", im.approximation.max_error_px},
                      {"pinhole_mean_error_px", im.approximation.mean_error_px},
                      {"ba_offset_px", {im.ba_offset_px.x(), im.ba_offset_px.y()}},
                      {"observations", im.observations}});
    if (im.sun_elevation_deg && im.sun_azimuth_deg) {
      images.back()["sun_elevation_deg"] = *im.sun_elevation_deg;
      images.back()["sun_azimuth_deg"] = *im.sun_azimuth_deg;
    }
  }
  const json doc = {
      {"schema", "skyfall.cameras/1"},
      {"aoi", c.aoi},
      {"frame", {{"type", "enu"},
                 {"origin", {{"lon_deg", c.enu_origin.lon_deg}, {"lat_deg", c.enu_origin.lat_deg},
                             {"height_m", c.enu_origin.height_m}}}}},
      {"conventions", "x_cam = R * X_enu + t; pixel = K * x_cam / z; top-left pixel centre at (0, 0)"},
      {"images", images}};
  return doc.dump(2) + "\n";
}

std::string ReportJson(const SfmResult& r) {
  json per_image = json::array();
  for (const SfmImage& im : r.images) {
    per_image.push_back({{"name", im.name},
                         {"used", im.used},
                         {"status", im.status},
                         {"keypoints", im.keypoints},
                         {"observations", im.observations},
                         {"dlt_max_error_px", im.approximation.max_error_px},
                         {"dlt_mean_error_px", im.approximation.mean_error_px},
                         {"skew_px", im.camera.skew},
                         {"ba_offset_px", {im.ba_offset_px.x(), im.ba_offset_px.y()}}});
  }
  json pairs = json::array();
  for (const PairStats& p : r.pairs) {
    pairs.push_back({{"a", r.images[p.a].name}, {"b", r.images[p.b].name}, {"ratio_matches", p.ratio_matches},
                     {"verified", p.verified}});
  }
  json doc = {{"status", ToString(r.report.status)},
              {"pairs", pairs},
              {"message", r.report.message},
              {"warnings", r.report.warnings},
              {"verified_pairs", r.verified_pairs},
              {"absolute_position", r.absolute_position},
              {"ba_mean_reproj_px_before", r.before.mean_px},
              {"ba_p90_reproj_px_before", r.before.p90_px},
              {"ba_mean_reproj_px_after", r.after.mean_px},
              {"ba_p90_reproj_px_after", r.after.p90_px},
              {"observations_after", r.after.count},
              {"per_image", per_image},
              {"seconds", r.report.seconds}};
  for (const auto& [k, v] : r.report.metrics) doc[k] = v;
  return doc.dump(2) + "\n";
}

// COLMAP's x for a pixel of the de-skewed image (and its +0.5 convention).
Eigen::Vector2d ColmapPixel(const PinholeCamera& cam, const Eigen::Vector2d& p) {
  const double shear = cam.skew / cam.fy;
  return {p.x() - shear * (p.y() - cam.cy) + 0.5, p.y() + 0.5};
}

void WriteDeskewedImage(const SfmImage& im, const std::string& path) {
  const NormalizedImage src = ReadNormalizedImage(im.path, im.radiometry);
  cv::Mat rgb(src.height_px, src.width_px, CV_8UC3);
  for (int r = 0; r < src.height_px; ++r)
    for (int c = 0; c < src.width_px; ++c)
      for (int b = 0; b < 3; ++b) {
        const float v = src.rgb[(static_cast<size_t>(r) * src.width_px + c) * 3 + b];
        rgb.at<cv::Vec3b>(r, c)[b] = static_cast<std::uint8_t>(v * 255.0f + 0.5f);
      }
  // Output pixel (x', y) samples the source at x = x' + shear * (y - cy).
  const double shear = im.camera.skew / im.camera.fy;
  const cv::Mat inverse = (cv::Mat_<double>(2, 3) << 1, shear, -shear * im.camera.cy, 0, 1, 0);
  cv::Mat out;
  cv::warpAffine(rgb, out, inverse, rgb.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT);
  WriteByteTiff(path, out.cols, out.rows, 3, out.ptr<std::uint8_t>());
}

void WriteColmap(const SfmResult& r, const fs::path& dir, bool images) {
  std::ostringstream cameras, imgs, pts;
  cameras << "# Camera list with one line of data per camera:\n"
          << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n";
  imgs << "# Image list with two lines of data per image:\n"
       << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
       << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  pts << "# 3D point list with one line of data per point:\n"
      << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n";
  cameras.precision(17);
  imgs.precision(17);
  pts.precision(17);
  // COLMAP ids start at 1; per image, the observations in point order.
  std::vector<int> colmap_id(r.images.size(), 0);
  int next = 1;
  for (size_t i = 0; i < r.images.size(); ++i)
    if (r.images[i].used) colmap_id[i] = next++;
  std::vector<std::vector<std::pair<Eigen::Vector2d, int>>> points2d(r.images.size());
  std::vector<std::vector<std::pair<int, int>>> point_tracks(r.points.size());
  for (size_t p = 0; p < r.points.size(); ++p) {
    for (const Observation& o : r.points[p].track) {
      const Eigen::Vector2d px = ColmapPixel(r.images[o.image].camera, o.pixel);
      point_tracks[p].emplace_back(colmap_id[o.image], static_cast<int>(points2d[o.image].size()));
      points2d[o.image].emplace_back(px, static_cast<int>(p) + 1);
    }
  }
  for (size_t i = 0; i < r.images.size(); ++i) {
    const SfmImage& im = r.images[i];
    if (!im.used) continue;
    const PinholeCamera& cam = im.camera;
    cameras << colmap_id[i] << " PINHOLE " << cam.width_px << " " << cam.height_px << " " << cam.fx << " "
            << cam.fy << " " << cam.cx + 0.5 << " " << cam.cy + 0.5 << "\n";
    const Eigen::Quaterniond q(cam.cam_from_world_rotation);
    const Eigen::Vector3d& t = cam.cam_from_world_translation;
    imgs << colmap_id[i] << " " << q.w() << " " << q.x() << " " << q.y() << " " << q.z() << " " << t.x() << " "
         << t.y() << " " << t.z() << " " << colmap_id[i] << " " << im.name << ".tif\n";
    for (size_t k = 0; k < points2d[i].size(); ++k) {
      imgs << (k ? " " : "") << points2d[i][k].first.x() << " " << points2d[i][k].first.y() << " "
           << points2d[i][k].second;
    }
    imgs << "\n";
    if (images) WriteDeskewedImage(im, (dir / "images" / (im.name + ".tif")).string());
  }
  for (size_t p = 0; p < r.points.size(); ++p) {
    const SfmPoint& pt = r.points[p];
    pts << p + 1 << " " << pt.enu_m.x() << " " << pt.enu_m.y() << " " << pt.enu_m.z() << " " << int(pt.rgb[0])
        << " " << int(pt.rgb[1]) << " " << int(pt.rgb[2]) << " " << pt.reprojection_error_px;
    for (const auto& [image, idx] : point_tracks[p]) pts << " " << image << " " << idx;
    pts << "\n";
  }
  WriteFileAtomic((dir / "cameras.txt").string(), cameras.str());
  WriteFileAtomic((dir / "images.txt").string(), imgs.str());
  WriteFileAtomic((dir / "points3D.txt").string(), pts.str());
}

}  // namespace

std::string PointsToPly(const SfmResult& r) {
  std::ostringstream out;
  out << "ply\nformat ascii 1.0\ncomment skyfall sfm points, ENU metres\nelement vertex " << r.points.size()
      << "\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\n"
         "property uchar blue\nproperty int track_length\nproperty float reprojection_error\nend_header\n";
  out.precision(12);
  for (const SfmPoint& p : r.points) {
    out << p.enu_m.x() << " " << p.enu_m.y() << " " << p.enu_m.z() << " " << int(p.rgb[0]) << " "
        << int(p.rgb[1]) << " " << int(p.rgb[2]) << " " << p.track.size() << " " << p.reprojection_error_px
        << "\n";
  }
  return out.str();
}

void WriteSfmOutputs(const SfmResult& r, const AoiCatalog& c, const std::string& out_dir, bool colmap_images) {
  const fs::path dir(out_dir);
  // The report goes last: a run killed while exporting leaves no report, so
  // a resuming driver redoes the stage instead of trusting half the files.
  if (r.report.status == StageStatus::kOk) {
    WriteFileAtomic((dir / "cameras.json").string(), CamerasJson(r, c));
    WriteFileAtomic((dir / "points.ply").string(), PointsToPly(r));
    WriteColmap(r, dir / "colmap", colmap_images);
  }
  WriteFileAtomic((dir / "sfm_report.json").string(), ReportJson(r));
}

}  // namespace skyfall
