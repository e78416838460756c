#include "catalogs/tile_catalog.h"

#include <filesystem>
#include <nlohmann/json.hpp>

#include "catalogs/json_doc.h"
#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall {

using json = nlohmann::json;

json BoxToJson(const GroundBox& b) {
  return {{"min_east_m", b.min_m.x()}, {"min_north_m", b.min_m.y()},
          {"max_east_m", b.max_m.x()}, {"max_north_m", b.max_m.y()}};
}

GroundBox BoxFromJson(const json& j) {
  GroundBox b;
  b.min_m = {j.at("min_east_m").get<double>(), j.at("min_north_m").get<double>()};
  b.max_m = {j.at("max_east_m").get<double>(), j.at("max_north_m").get<double>()};
  return b;
}

namespace {

}  // namespace

std::string TileSpecToJson(const TileSpec& t) {
  json images = json::array();
  for (const TileImage& im : t.images) {
    images.push_back({{"name", im.name},
                      {"source_path", im.source_path},
                      {"crop_path", im.crop_path},
                      {"window_px", {im.col0_px, im.row0_px, im.width_px, im.height_px}},
                      {"coverage", im.coverage}});
  }
  const json doc = {
      {"schema", kTileSchema},
      {"id", t.id},
      {"city", t.city},
      {"aois", t.aois},
      {"col", t.col},
      {"row", t.row},
      {"grid", {{"origin_east_m", t.grid.origin_m.x()}, {"origin_north_m", t.grid.origin_m.y()},
                {"tile_m", t.grid.tile_m}, {"overlap_m", t.grid.overlap_m},
                {"cols", t.grid.cols}, {"rows", t.grid.rows}}},
      {"core", BoxToJson(t.core)},
      {"extent", BoxToJson(t.extent)},
      {"enu_origin", {{"lon_deg", t.enu_origin.lon_deg}, {"lat_deg", t.enu_origin.lat_deg},
                      {"height_m", t.enu_origin.height_m}}},
      {"height_range_m", {t.min_ellipsoid_height_m, t.max_ellipsoid_height_m}},
      {"images", images}};
  return doc.dump(2) + "\n";
}

TileSpec TileSpecFromJson(const std::string& text, const std::string& subject) {
  const json doc = catalogs::ParseVersioned(text, subject, kTileSchema);
  TileSpec t;
  try {
    t.id = doc.at("id").get<std::string>();
    t.city = doc.at("city").get<std::string>();
    t.aois = doc.at("aois").get<std::vector<std::string>>();
    t.col = catalogs::JsonInt(doc.at("col"), subject, "col");
    t.row = catalogs::JsonInt(doc.at("row"), subject, "row");
    const json& g = doc.at("grid");
    t.grid.origin_m = {g.at("origin_east_m").get<double>(), g.at("origin_north_m").get<double>()};
    t.grid.tile_m = g.at("tile_m").get<double>();
    t.grid.overlap_m = g.at("overlap_m").get<double>();
    t.grid.cols = catalogs::JsonInt(g.at("cols"), subject, "cols");
    t.grid.rows = catalogs::JsonInt(g.at("rows"), subject, "rows");
    t.core = BoxFromJson(doc.at("core"));
    t.extent = BoxFromJson(doc.at("extent"));
    const json& o = doc.at("enu_origin");
    t.enu_origin = {o.at("lon_deg").get<double>(), o.at("lat_deg").get<double>(), o.at("height_m").get<double>()};
    t.min_ellipsoid_height_m = doc.at("height_range_m").at(0).get<double>();
    t.max_ellipsoid_height_m = doc.at("height_range_m").at(1).get<double>();
    for (const json& j : doc.at("images")) {
      TileImage im;
      im.name = j.at("name").get<std::string>();
      im.source_path = j.at("source_path").get<std::string>();
      im.crop_path = j.at("crop_path").get<std::string>();
      const auto w = j.at("window_px").get<std::vector<int>>();
      if (w.size() != 4) throw Error("catalog", subject, "images[" + im.name + "].window_px must hold 4 integers");
      im.col0_px = w[0], im.row0_px = w[1], im.width_px = w[2], im.height_px = w[3];
      im.coverage = j.value("coverage", 0.0);
      t.images.push_back(im);
    }
  } catch (const json::exception& e) {
    throw Error("catalog", subject, std::string("missing or bad field: ") + e.what());
  }
  if (t.grid.cols < 1 || t.grid.rows < 1 || !(t.grid.tile_m > 0)) {
    throw Error("catalog", subject, "grid must have cols, rows >= 1 and tile_m > 0");
  }
  return t;
}

TileSpec ReadTileSpec(const std::string& path) {
  return TileSpecFromJson(ReadTextFile(path), path);
}

std::string TileReconstructionPath(const std::string& tile_dir) {
  return (std::filesystem::path(tile_dir) / "splat" / "scene.ply").string();
}

std::string TileSurfacePath(const std::string& tile_dir) {
  const std::filesystem::path surface = std::filesystem::path(tile_dir) / "splat" / "surface.ply";
  return std::filesystem::exists(surface) ? surface.string() : TileReconstructionPath(tile_dir);
}

std::string TileScenePath(const std::string& tile_dir) {
  const std::filesystem::path idu = std::filesystem::path(tile_dir) / "idu" / "scene.ply";
  return std::filesystem::exists(idu) ? idu.string() : TileReconstructionPath(tile_dir);
}

}  // namespace skyfall
