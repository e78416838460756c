#include "splat/dataset.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"
#include "catalogs/aoi_catalog.h"
#include "ingest/radiometry.h"
#include "catalogs/json_doc.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

PinholeCamera CameraFromJson(const json& j) {
  PinholeCamera c;
  // at(): a short or malformed matrix is a json::exception (named by the
  // caller), never a read past the end.
  const auto K = j.at("K"), R = j.at("R"), t = j.at("t");
  c.fx = K.at(0).at(0);
  c.skew = K.at(0).at(1);
  c.cx = K.at(0).at(2);
  c.fy = K.at(1).at(1);
  c.cy = K.at(1).at(2);
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) c.cam_from_world_rotation(r, k) = R.at(r).at(k);
    c.cam_from_world_translation[r] = t.at(r);
  }
  c.width_px = catalogs::JsonInt(j.at("width_px"), "cameras.json", "width_px");
  c.height_px = catalogs::JsonInt(j.at("height_px"), "cameras.json", "height_px");
  return c;
}

}  // namespace

PinholeCamera DownscaledCamera(const PinholeCamera& camera, int s) {
  PinholeCamera c = camera;
  c.fx /= s;
  c.fy /= s;
  c.skew /= s;
  // Pixel centres at integers: full-resolution x maps to (x + 0.5) / s - 0.5.
  c.cx = (camera.cx + 0.5) / s - 0.5;
  c.cy = (camera.cy + 0.5) / s - 0.5;
  c.width_px = camera.width_px / s;
  c.height_px = camera.height_px / s;
  return c;
}

void ThinToGrid(double spacing_m, const std::vector<Eigen::Vector3f>& dense,
                const std::vector<Eigen::Vector3f>& dense_colours, const std::vector<Eigen::Vector3f>& extra,
                const std::vector<Eigen::Vector3f>& extra_colours, std::vector<Eigen::Vector3f>* points,
                std::vector<Eigen::Vector3f>* colours, const std::vector<std::uint8_t>* keep_all) {
  if (!(spacing_m > 0)) throw Error("splat", "init spacing", std::to_string(spacing_m) + " m must be > 0");
  if (dense.size() != dense_colours.size() || extra.size() != extra_colours.size() ||
      (keep_all && keep_all->size() != dense.size()))
    throw Error("splat", "init points", "points and colours differ in number");
  std::set<std::pair<std::int64_t, std::int64_t>> taken;
  std::vector<Eigen::Vector3f> out_points, out_colours;
  auto cell_of = [&](const Eigen::Vector3f& p) {
    return std::make_pair(static_cast<std::int64_t>(std::floor(p.x() / spacing_m)),
                          static_cast<std::int64_t>(std::floor(p.y() / spacing_m)));
  };
  auto add_if_free = [&](const Eigen::Vector3f& p, const Eigen::Vector3f& c) {
    if (!taken.insert(cell_of(p)).second) return;
    out_points.push_back(p);
    out_colours.push_back(c);
  };
  const auto kept = [&](std::size_t k) { return keep_all && (*keep_all)[k]; };
  for (std::size_t k = 0; k < dense.size(); ++k) {
    if (!kept(k)) continue;
    taken.insert(cell_of(dense[k]));
    out_points.push_back(dense[k]);
    out_colours.push_back(dense_colours[k]);
  }
  for (std::size_t k = 0; k < dense.size(); ++k)
    if (!kept(k)) add_if_free(dense[k], dense_colours[k]);
  for (std::size_t k = 0; k < extra.size(); ++k) add_if_free(extra[k], extra_colours[k]);
  *points = std::move(out_points);
  *colours = std::move(out_colours);
}

void FacadePoints(const std::vector<Eigen::Vector3f>& grid_points, const std::vector<Eigen::Vector3f>& colours,
                  double cell_m, double spacing_m, double min_step_m, std::vector<Eigen::Vector3f>* points,
                  std::vector<Eigen::Vector3f>* out_colours, std::vector<int>* normal_axis) {
  if (!(cell_m > 0) || !(spacing_m > 0) || !(min_step_m > 0))
    throw Error("splat", "facade points", "cell, spacing and step must be > 0");
  if (grid_points.size() != colours.size()) throw Error("splat", "facade points", "points and colours differ in number");
  points->clear();
  out_colours->clear();
  normal_axis->clear();
  if (grid_points.empty()) return;
  // The cells by grid index.
  using Key = std::pair<std::int64_t, std::int64_t>;
  Eigen::Vector2f origin = grid_points[0].head<2>();
  for (const Eigen::Vector3f& p : grid_points) origin = origin.cwiseMin(p.head<2>());
  auto key_of = [&](const Eigen::Vector3f& p) {
    return Key(std::llround((p.x() - origin.x()) / cell_m), std::llround((p.y() - origin.y()) / cell_m));
  };
  std::map<Key, std::size_t> cell;
  for (std::size_t k = 0; k < grid_points.size(); ++k) cell.emplace(key_of(grid_points[k]), k);
  // Along a wall, one column every spacing_m: every n-th cell edge.
  const std::int64_t every = std::max<std::int64_t>(1, std::llround(spacing_m / cell_m));
  for (const auto& [key, k] : cell) {
    static constexpr int kSides[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    for (const auto& side : kSides) {
      const auto found = cell.find(Key(key.first + side[0], key.second + side[1]));
      if (found == cell.end()) continue;
      const Eigen::Vector3f& high = grid_points[k];
      const Eigen::Vector3f& low = grid_points[found->second];
      if (high.z() - low.z() < min_step_m) continue;
      const std::int64_t along = side[0] != 0 ? key.second : key.first;  // position along the wall
      if (along % every != 0) continue;
      const Eigen::Vector2f edge = 0.5f * (high.head<2>() + low.head<2>());
      const int rows = std::max(1, static_cast<int>(std::floor((high.z() - low.z()) / spacing_m)));
      for (int r = 0; r < rows; ++r) {
        const float z = low.z() + (r + 0.5f) * (high.z() - low.z()) / rows;
        points->emplace_back(edge.x(), edge.y(), z);
        out_colours->push_back(colours[found->second]);
        normal_axis->push_back(side[0] != 0 ? 0 : 1);
      }
    }
  }
}

std::vector<CameraEntry> ReadCameraEntries(const std::string& path) {
  return ParseCameraEntries(ReadTextFile(path), path);
}

std::vector<CameraEntry> ParseCameraEntries(const std::string& text, const std::string& path) {
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {
    throw Error("splat", path, std::string("not valid JSON: ") + e.what());
  }
  std::vector<CameraEntry> out;
  try {
    for (const json& im : doc.at("images")) {
      if (!im.value("used", true)) continue;
      CameraEntry e;
      e.name = im.at("name").get<std::string>();
      e.camera = CameraFromJson(im);
      e.source_image = im.value("source_image", std::string());
      e.held_out = im.value("split", std::string("train")) == "test";
      e.acquisition_time = im.value("acquisition_time", std::string());
      // Both angles as numbers, or the sun is unknown (null: not stated).
      const json* el = im.contains("sun_elevation_deg") ? &im.at("sun_elevation_deg") : nullptr;
      const json* az = im.contains("sun_azimuth_deg") ? &im.at("sun_azimuth_deg") : nullptr;
      if (el && az && !el->is_null() && !az->is_null()) e.sun = {el->get<double>(), az->get<double>()};
      if (im.contains("radiometry") && !im.at("radiometry").is_null())
        e.radiometry = RadiometryFromJson(im.at("radiometry").dump(), path + ": " + e.name + ".radiometry");
      out.push_back(std::move(e));
    }
  } catch (const json::exception& e) {
    throw Error("splat", path, std::string("bad camera entry: ") + e.what());
  }
  return out;
}

GeodeticPoint ReadCamerasFrameOrigin(const std::string& path) {
  try {
    const json o = json::parse(ReadTextFile(path)).at("frame").at("origin");
    return {o.at("lon_deg").get<double>(), o.at("lat_deg").get<double>(), o.at("height_m").get<double>()};
  } catch (const json::exception& e) {
    throw Error("splat", path, std::string("no frame.origin: ") + e.what());
  }
}

std::vector<std::pair<std::string, PinholeCamera>> ReadCameras(const std::string& path) {
  std::vector<std::pair<std::string, PinholeCamera>> out;
  for (CameraEntry& e : ReadCameraEntries(path)) out.emplace_back(std::move(e.name), e.camera);
  return out;
}

std::vector<TrainView> LoadTrainViews(const std::string& sfm_dir, int downscale) {
  if (downscale < 1) throw Error("splat", "resolution", "downscale factor must be >= 1");
  const std::string path = (fs::path(sfm_dir) / "cameras.json").string();
  std::vector<TrainView> views;
  for (const CameraEntry& entry : ReadCameraEntries(path)) {
    if (entry.source_image.empty()) throw Error("splat", path, "image '" + entry.name + "' has no source_image");
    TrainView v;
    v.name = entry.name;
    v.held_out = entry.held_out;
    v.acquisition_time = entry.acquisition_time;
    v.sun = entry.sun;
    const PinholeCamera& full = entry.camera;
    v.camera = DownscaledCamera(full, downscale);
    const NormalizedImage img = ReadNormalizedImage(entry.source_image, entry.radiometry);
    if (img.width_px != full.width_px || img.height_px != full.height_px) {
      throw Error("splat", entry.source_image, "size differs from cameras.json");
    }
    const int w = v.camera.width_px, h = v.camera.height_px;
    v.rgb.assign(3 * static_cast<size_t>(w) * h, 0.0f);
    v.valid.assign(static_cast<size_t>(w) * h, 1);
    const float norm = 1.0f / static_cast<float>(downscale * downscale);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        // A training pixel holds data only when every source pixel in it does.
        std::uint8_t all_valid = 1;
        for (int c = 0; c < 3; ++c) {
          float s = 0;
          for (int dy = 0; dy < downscale; ++dy)
            for (int dx = 0; dx < downscale; ++dx) {
              const size_t p = static_cast<size_t>(y * downscale + dy) * img.width_px + (x * downscale + dx);
              s += img.rgb[3 * p + c];
              all_valid &= img.valid[p];
            }
          v.rgb[(static_cast<size_t>(y) * w + x) * 3 + c] = s * norm;
        }
        v.valid[static_cast<size_t>(y) * w + x] = all_valid;
      }
    views.push_back(std::move(v));
  }
  if (views.empty()) throw Error("splat", path, "lists no used image");
  return views;
}

void ReadSfmPoints(const std::string& path, std::vector<Eigen::Vector3f>* points, std::vector<Eigen::Vector3f>* colours) {
  std::istringstream in(ReadTextFile(path));
  std::string line;
  size_t count = 0;
  bool ascii = false;
  while (std::getline(in, line) && line != "end_header") {
    if (line.rfind("element vertex", 0) == 0) count = std::stoul(line.substr(15));
    if (line == "format ascii 1.0") ascii = true;
  }
  if (!ascii) throw Error("splat", path, "expected the ASCII points.ply written by `skyfall sfm`");
  for (size_t i = 0; i < count; ++i) {
    double x, y, z;
    int r, g, b;
    if (!std::getline(in, line)) throw Error("splat", path, "truncated at point " + std::to_string(i));
    std::istringstream ls(line);
    if (!(ls >> x >> y >> z >> r >> g >> b)) throw Error("splat", path, "bad point line " + std::to_string(i));
    points->emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    colours->emplace_back(r / 255.0f, g / 255.0f, b / 255.0f);
  }
}

}  // namespace skyfall
