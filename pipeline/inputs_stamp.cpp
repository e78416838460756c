#include "pipeline/inputs_stamp.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "catalogs/aoi_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/sha256.h"
#include "catalogs/tile_catalog.h"
#include "core/tile.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Size and modification time (ns) of a file; throws Error naming it.
json FileStat(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) throw Error("run", path, std::string("cannot stat: ") + std::strerror(errno));
  const long long mtime_ns = static_cast<long long>(st.st_mtim.tv_sec) * 1000000000LL + st.st_mtim.tv_nsec;
  return {{"path", path}, {"size_bytes", static_cast<long long>(st.st_size)}, {"mtime_ns", mtime_ns}};
}

json TruthFileStamp(const std::string& path) {
  if (path.empty()) return nullptr;
  json stamp = FileStat(path);
  stamp["sha256"] = Sha256FileHex(path);
  return stamp;
}

// Removed when a tile's inputs change: everything a tile computes.
constexpr const char* kTileProducts[] = {"sfm", "splat", "idu", "tile_report.json"};

}  // namespace

std::map<std::string, json> ImageStamps(const std::vector<AoiCatalog>& aois) {
  std::map<std::string, json> stamps;
  for (const AoiCatalog& a : aois) {
    const json catalog = json::parse(AoiCatalogToJson(a));
    for (const json& image : catalog.at("images")) {
      const std::string path = image.at("path");
      json stamp = FileStat(path);
      stamp["rpc_sha256"] = Sha256Hex(image.at("rpc").dump());
      stamps[path] = stamp;
    }
  }
  return stamps;
}

std::string ResultOptionsSha256(const RunOptions& options) {
  json doc = json::parse(RunOptionsToJson(options));
  doc.erase("executor");  // how tiles are scheduled does not change results
  return Sha256Hex(doc.dump());
}

json CityInputsStamp(const RunOptions& options, const std::vector<AoiCatalog>& aois,
                     const std::map<std::string, json>& image_stamps) {
  json list = json::array();
  for (const AoiCatalog& a : aois) {
    json images = json::array();
    for (const ImageRecord& im : a.images) images.push_back(image_stamps.at(im.path));
    json truth = nullptr;
    if (a.truth) {
      truth = {{"dsm", TruthFileStamp(a.truth->dsm_path)}, {"dsm_txt", TruthFileStamp(a.truth->dsm_txt_path)},
               {"cls", TruthFileStamp(a.truth->cls_path)}};
    }
    list.push_back({{"aoi", a.aoi}, {"images", images}, {"truth", truth}});
  }
  return {{"schema", "skyfall.inputs/1"}, {"aois", list}, {"options_sha256", ResultOptionsSha256(options)}};
}

json TileInputsStamp(const std::string& tile_dir, const std::map<std::string, json>& image_stamps) {
  const TileSpec spec = ReadTileSpec((fs::path(tile_dir) / "tile.json").string());
  json images = json::array();
  for (const TileImage& im : spec.images) {
    const auto it = image_stamps.find(im.source_path);
    images.push_back(it != image_stamps.end() ? it->second : FileStat(im.source_path));
  }
  json stamp = {{"schema", "skyfall.tile_inputs/1"}, {"images", images}};
  // The acquisitions that fix the tile's frame (AoiCatalog::gauge_acquisitions):
  // the same images in another frame are another reconstruction.
  const fs::path catalog_path = fs::path(tile_dir) / "aoi.json";
  if (fs::exists(catalog_path)) {
    const AoiCatalog catalog = ReadAoiCatalog(catalog_path.string());
    if (!catalog.gauge_acquisitions.empty()) stamp["gauge_acquisitions"] = catalog.gauge_acquisitions;
  }
  return stamp;
}

bool ResetTileIfInputsChanged(const std::string& tile_dir, const json& stamp) {
  const fs::path stamp_path = fs::path(tile_dir) / "inputs.json";
  bool same = false;
  try {
    same = fs::exists(stamp_path) && json::parse(ReadTextFile(stamp_path.string())) == stamp;
  } catch (const std::exception&) {
    same = false;  // an unreadable stamp is a changed one
  }
  if (same) return false;
  bool had_products = false;
  for (const char* product : kTileProducts) {
    const fs::path p = fs::path(tile_dir) / product;
    if (!fs::exists(p)) continue;
    had_products = true;
    std::error_code ec;
    fs::remove_all(p, ec);
    if (ec) throw Error("run", p.string(), "cannot remove the products of changed inputs: " + ec.message());
  }
  WriteFileAtomic(stamp_path.string(), stamp.dump(2) + "\n");
  return had_products;
}

}  // namespace skyfall
