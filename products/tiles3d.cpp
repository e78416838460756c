#include "products/tiles3d.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <unordered_map>
#include <unordered_set>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "products/spz.h"
#include "splat/gaussian_spill.h"
#include "splat/ply.h"
#include "ingest/geo.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr int kFloat = 5126, kUnsignedByte = 5121;
constexpr std::uint32_t kGlbMagic = 0x46546c67, kJsonChunk = 0x4e4f534a, kBinChunk = 0x004e4942;
// [sigma] a Gaussian's footprint reaches this many standard deviations (the
// rendering kernel's cut-off): bounding volumes hold it.
constexpr double kFootprintSigmas = 3.0;

void PutU32(std::string* out, std::uint32_t v) {
  for (int b = 0; b < 4; ++b) out->push_back(static_cast<char>((v >> (8 * b)) & 0xff));
}

json Accessor(std::size_t count, const char* type, int component_type, bool normalized = false) {
  json a = {{"count", count}, {"type", type}, {"componentType", component_type}};
  if (normalized) a["normalized"] = true;
  return a;
}

struct LodLevel {
  int level = 0;
  double geometric_error_m = 0;
  std::string path;  // its PLY, read a chunk at a time
};

struct Area {
  double x0, y0, x1, y1;
  double Width() const { return std::max(x1 - x0, y1 - y0); }
};

struct ZRange {
  double lo = INFINITY, hi = -INFINITY;
  void Add(const ZRange& o) { lo = std::min(lo, o.lo), hi = std::max(hi, o.hi); }
  bool Empty() const { return !(lo <= hi); }
};

// Quadrant q of `a`: bit 0 east, bit 1 north (0 west-south, 1 east-south,
// 2 west-north, 3 east-north).
Area Quadrant(const Area& a, int q) {
  const double mx = 0.5 * (a.x0 + a.x1), my = 0.5 * (a.y0 + a.y1);
  const bool east = q & 1, north = q & 2;
  return {east ? mx : a.x0, north ? my : a.y0, east ? a.x1 : mx, north ? a.y1 : my};
}

// The quadrants of `a` in Quadrant's order, or `a` alone once it is no wider
// than a leaf: the next level refines in place.
std::vector<Area> Split(const Area& a, double leaf_m) {
  if (a.Width() <= leaf_m) return {a};
  return {Quadrant(a, 0), Quadrant(a, 1), Quadrant(a, 2), Quadrant(a, 3)};
}

// The node `depth` levels below `root` whose half-open area holds `p`, named
// by the branches of the descent: a quadrant's index as in Split, 's' where a
// node does not split. A node of depth d holds the Gaussians of LOD level
// index (levels - 1 - d), so the key also says the level.
std::string NodeKey(Area area, int depth, const Eigen::Vector3f& p, double leaf_m) {
  std::string key;
  for (int d = 0; d < depth; ++d) {
    if (area.Width() <= leaf_m) {
      key += 's';
      continue;
    }
    const int q = (p.x() >= 0.5 * (area.x0 + area.x1) ? 1 : 0) + (p.y() >= 0.5 * (area.y0 + area.y1) ? 2 : 0);
    key += static_cast<char>('0' + q);
    area = Quadrant(area, q);
  }
  return key;
}

// Each node's Gaussians, gathered on disk while the levels are streamed, so
// that memory holds at most `budget_bytes` of them plus one node's cloud,
// whatever the city's size. A node's records keep the order of its level's
// file. The folder is removed when the spill is destroyed.
class NodeSpill {
 public:
  NodeSpill(fs::path dir, std::size_t budget_bytes) : spill_(std::move(dir), kSpilledGaussianBytes, budget_bytes) {}

  void Add(const std::string& key, const GaussianCloud& chunk, std::size_t i) {
    if (occupied_.insert(key).second) {
      for (std::size_t n = 0; n < key.size(); ++n) occupied_.insert(key.substr(0, n));  // its ancestors
    }
    SpillGaussian(spill_, key, chunk, i);
  }
  void Flush() { spill_.Flush(); }
  // Whether the node or one below it holds a Gaussian.
  bool Occupied(const std::string& key) const { return occupied_.count(key) > 0; }
  // The node's Gaussians (none when it holds none), then forgotten.
  GaussianCloud Take(const std::string& key) {
    GaussianCloud cloud = ReadSpilledGaussians(spill_, key);
    spill_.Remove(key);
    return cloud;
  }

 private:
  KeyedSpill spill_;
  std::unordered_set<std::string> occupied_;
};

class TreeWriter {
 public:
  TreeWriter(const std::vector<LodLevel>& levels, const Tiles3dOptions& options, const fs::path& out_dir,
             NodeSpill* spill)
      : levels_(levels), options_(options), out_dir_(out_dir), spill_(spill) {}

  // The node `key` for `area` at LOD level index `k` (0 = finest) and its
  // subtree, written depth first; null when nothing of any level below it
  // lies in the area.
  json Build(const Area& area, std::size_t k, const std::string& key, ZRange* z_out) {
    if (!spill_->Occupied(key)) return nullptr;
    GaussianCloud subset = spill_->Take(key);
    ZRange z = Heights(subset);
    json children = json::array();
    double child_error = 0;
    if (k > 0) {
      const std::vector<Area> parts = Split(area, options_.leaf_m);
      for (std::size_t q = 0; q < parts.size(); ++q) {
        ZRange child_z;
        const std::string child_key = key + (parts.size() == 1 ? 's' : static_cast<char>('0' + q));
        json child = Build(parts[q], k - 1, child_key, &child_z);
        if (child.is_null()) continue;
        child_error = std::max(child_error, child.at("geometricError").get<double>());
        z.Add(child_z);
        children.push_back(std::move(child));
      }
    }
    if (subset.size() == 0 && children.empty()) return nullptr;
    ++summary.tiles;
    // A parent's error is never below its children's (3D Tiles requires it).
    json node = {{"boundingVolume", {{"box", Box(area, z)}}},
                 {"geometricError", std::max(levels_[k].geometric_error_m, child_error)}};
    if (subset.size() > 0) {
      const std::string uri = fmt::format("content/t{}.glb", summary.contents++);
      const std::vector<std::uint8_t> glb = SplatGlb(subset, SpzFractionalBits(subset, options_.max_fractional_bits));
      WriteFileAtomic((out_dir_ / uri).string(), std::string(glb.begin(), glb.end()));
      node["content"] = {{"uri", uri}};
      summary.gaussians += subset.size();
    }
    if (!children.empty()) node["children"] = std::move(children);
    *z_out = z;
    return node;
  }

  Tiles3dSummary summary;

 private:
  static ZRange Heights(const GaussianCloud& cloud) {
    ZRange z;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      const double reach = kFootprintSigmas * std::exp(cloud.log_scales[i].maxCoeff());
      z.lo = std::min(z.lo, cloud.means[i].z() - reach);
      z.hi = std::max(z.hi, cloud.means[i].z() + reach);
    }
    return z;
  }

  // 3D Tiles box: centre, then the three half-axis vectors, in the ENU frame.
  // Its horizontal extent is the area; footprints that cross the area's edge
  // are left to the neighbour's volume (they are small against a tile).
  static json Box(const Area& a, ZRange z) {
    if (z.Empty()) z = {0, 0};
    const double half_z = std::max(0.5 * (z.hi - z.lo), 0.5);
    return {0.5 * (a.x0 + a.x1), 0.5 * (a.y0 + a.y1), 0.5 * (z.lo + z.hi), 0.5 * (a.x1 - a.x0), 0, 0, 0,
            0.5 * (a.y1 - a.y0), 0, 0, 0, half_z};
  }

  const std::vector<LodLevel>& levels_;
  const Tiles3dOptions& options_;
  fs::path out_dir_;
  NodeSpill* spill_;
};

json ReadJsonFile(const fs::path& path) {
  try {
    return json::parse(ReadTextFile(path.string()));
  } catch (const json::exception& e) {
    throw Error("3dtiles", path.string(), std::string("not valid JSON: ") + e.what());
  }
}

}  // namespace

void Tiles3dOptions::Check() const { CheckOptionRanges(*this, "3dtiles"); }

std::vector<std::uint8_t> SplatGlb(const GaussianCloud& cloud, int fractional_bits) {
  const std::vector<std::uint8_t> spz = EncodeSpz(cloud, fractional_bits);
  const std::size_t n = cloud.size();
  // POSITION needs min/max: those of the positions as SPZ stores them.
  const double step = std::ldexp(1.0, -fractional_bits);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (const auto& m : cloud.means) {
    const Eigen::Vector3d q = (m.cast<double>() / step).array().round() * step;
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  json position = Accessor(n, "VEC3", kFloat);
  position["min"] = {lo.x(), lo.y(), lo.z()};
  position["max"] = {hi.x(), hi.y(), hi.z()};
  // The attributes the SPZ stream fills (KHR_gaussian_splatting_compression_spz_2
  // mapping): accessors give type and count only, no bufferView.
  const json accessors = {position,
                          Accessor(n, "VEC4", kUnsignedByte, true),  // COLOR_0: DC colour and opacity
                          Accessor(n, "VEC3", kFloat),               // scale
                          Accessor(n, "VEC4", kFloat),               // rotation (x, y, z, w)
                          Accessor(n, "VEC3", kFloat), Accessor(n, "VEC3", kFloat), Accessor(n, "VEC3", kFloat)};
  const json attributes = {{"POSITION", 0},
                           {"COLOR_0", 1},
                           {"KHR_gaussian_splatting:SCALE", 2},
                           {"KHR_gaussian_splatting:ROTATION", 3},
                           {"KHR_gaussian_splatting:SH_DEGREE_1_COEF_0", 4},
                           {"KHR_gaussian_splatting:SH_DEGREE_1_COEF_1", 5},
                           {"KHR_gaussian_splatting:SH_DEGREE_1_COEF_2", 6}};
  const json splat = {{"kernel", "ellipse"},
                      {"colorSpace", "srgb_rec709_display"},
                      {"extensions", {{"KHR_gaussian_splatting_compression_spz_2", {{"bufferView", 0}}}}}};
  const std::size_t bin_length = (spz.size() + 3) / 4 * 4;
  const json gltf = {
      {"asset", {{"version", "2.0"}, {"generator", "skyfall"}}},
      {"extensionsUsed", {"KHR_gaussian_splatting", "KHR_gaussian_splatting_compression_spz_2"}},
      {"extensionsRequired", {"KHR_gaussian_splatting", "KHR_gaussian_splatting_compression_spz_2"}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes", {{{"mesh", 0}, {"matrix", std::vector<double>(std::begin(kZUpToYUp), std::end(kZUpToYUp))}}}},
      {"meshes",
       {{{"primitives",
          {{{"mode", 0}, {"attributes", attributes}, {"extensions", {{"KHR_gaussian_splatting", splat}}}}}}}}},
      {"accessors", accessors},
      {"bufferViews", {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", spz.size()}}}},
      {"buffers", {{{"byteLength", bin_length}}}}};
  std::string text = gltf.dump();
  text.resize((text.size() + 3) / 4 * 4, ' ');  // chunks are 4-byte aligned; JSON pads with spaces
  std::string glb;
  PutU32(&glb, kGlbMagic);
  PutU32(&glb, 2);
  PutU32(&glb, static_cast<std::uint32_t>(12 + 8 + text.size() + 8 + bin_length));
  PutU32(&glb, static_cast<std::uint32_t>(text.size()));
  PutU32(&glb, kJsonChunk);
  glb += text;
  PutU32(&glb, static_cast<std::uint32_t>(bin_length));
  PutU32(&glb, kBinChunk);
  glb.append(reinterpret_cast<const char*>(spz.data()), spz.size());
  glb.resize(glb.size() + (bin_length - spz.size()), '\0');
  return std::vector<std::uint8_t>(glb.begin(), glb.end());
}

Tiles3dSummary Export3dTiles(const std::string& scene_dir, const std::string& out_dir, const Tiles3dOptions& options,
                             Progress& progress) {
  options.Check();
  Stopwatch clock;
  const fs::path scene(scene_dir), out(out_dir);
  const json lod = ReadJsonFile(scene / "lod.json");
  const json frame = ReadJsonFile(scene / "frame.json");
  GeodeticPoint origin;
  try {
    origin.lon_deg = frame.at("enu_origin").at("lon_deg");
    origin.lat_deg = frame.at("enu_origin").at("lat_deg");
    origin.height_m = frame.at("enu_origin").at("height_m");
  } catch (const json::exception& e) {
    throw Error("3dtiles", (scene / "frame.json").string(), std::string("enu_origin: ") + e.what());
  }
  std::vector<LodLevel> levels;
  try {
    for (const json& l : lod.at("levels")) {
      LodLevel level;
      level.level = l.at("level");
      level.geometric_error_m = l.at("geometric_error_m");
      level.path = (scene / l.at("file").get<std::string>()).string();
      levels.push_back(std::move(level));
    }
  } catch (const json::exception& e) {
    throw Error("3dtiles", (scene / "lod.json").string(), std::string("levels: ") + e.what());
  }
  if (levels.empty()) throw Error("3dtiles", (scene / "lod.json").string(), "lists no level");
  std::sort(levels.begin(), levels.end(), [](const LodLevel& a, const LodLevel& b) { return a.level < b.level; });
  // The root area: a square around every Gaussian of every level, so that
  // quadrants stay square. The levels are streamed twice (here, then into
  // their nodes), never held whole.
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(INFINITY), hi = -lo;
  for (const LodLevel& l : levels) {
    ForEachGaussiansPlyChunk(l.path, [&](const GaussianCloud& chunk) {
      for (const auto& m : chunk.means) {
        lo = lo.cwiseMin(m.head<2>().cast<double>());
        hi = hi.cwiseMax(m.head<2>().cast<double>());
      }
    });
  }
  if (!(lo.x() <= hi.x())) throw Error("3dtiles", scene_dir, "the scene holds no Gaussian");
  const double side = (hi - lo).maxCoeff() + 1e-3;  // half-open areas: the last Gaussian stays inside
  const Area root_area{lo.x(), lo.y(), lo.x() + side, lo.y() + side};
  progress.Info(fmt::format("3dtiles: {} LOD level(s) over {:.0f} m, leaves up to {:.0f} m", levels.size(), side,
                            options.leaf_m));
  fs::create_directories(out / "content");
  NodeSpill spill(out / ".spill", static_cast<std::size_t>(options.spill_buffer_mb * 1e6));
  for (std::size_t j = 0; j < levels.size(); ++j) {
    const int depth = static_cast<int>(levels.size() - 1 - j);
    ForEachGaussiansPlyChunk(levels[j].path, [&](const GaussianCloud& chunk) {
      for (std::size_t i = 0; i < chunk.size(); ++i)
        spill.Add(NodeKey(root_area, depth, chunk.means[i], options.leaf_m), chunk, i);
    });
  }
  spill.Flush();
  TreeWriter writer(levels, options, out, &spill);
  ZRange z;
  json root = writer.Build(root_area, levels.size() - 1, "", &z);
  const Eigen::Matrix4d ecef_from_enu = EnuFrame(origin).EcefFromEnu();
  std::vector<double> transform(16);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) transform[4 * c + r] = ecef_from_enu(r, c);  // column-major
  root["transform"] = transform;
  root["refine"] = "REPLACE";
  const double diagonal = std::hypot(side, side, z.hi - z.lo);
  const json splats = {"KHR_gaussian_splatting", "KHR_gaussian_splatting_compression_spz_2"};
  const json tileset = {
      {"asset", {{"version", "1.1"}, {"generator", "skyfall"}}},
      {"extensionsUsed", {"3DTILES_content_gltf"}},
      {"extensions", {{"3DTILES_content_gltf", {{"extensionsUsed", splats}, {"extensionsRequired", splats}}}}},
      {"geometricError", std::max(diagonal, 2 * root.at("geometricError").get<double>())},
      {"root", root}};
  Tiles3dSummary summary = writer.summary;
  summary.tileset_path = (out / "tileset.json").string();
  summary.levels = static_cast<int>(levels.size());
  WriteFileAtomic(summary.tileset_path, tileset.dump(1) + "\n");
  summary.seconds = clock.Seconds();
  progress.Info(fmt::format("3dtiles: {} tiles, {} GLB files, {} Gaussians in {:.1f} s -> {}", summary.tiles,
                            summary.contents, summary.gaussians, summary.seconds, summary.tileset_path));
  return summary;
}

}  // namespace skyfall
