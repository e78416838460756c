#include "products/stac.h"

#include <gdal.h>
#include <cpl_conv.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "core/sha256.h"
#include "core/tile.h"
#include "catalogs/tile_catalog.h"
#include "ingest/gdal_util.h"
#include "ingest/geo.h"
#include "ingest/vertical_datum.h"
#include "products/point_cloud.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr const char* kGeoTiff = "image/tiff; application=geotiff";
constexpr const char* kCog = "image/tiff; application=geotiff; profile=cloud-optimized";
constexpr const char* kPng = "image/png";
constexpr const char* kJson = "application/json";
constexpr const char* kGeoJson = "application/geo+json";
constexpr const char* kCsv = "text/csv";
constexpr const char* kPly = "application/ply";

std::string Relative(const fs::path& target, const fs::path& from_dir) {
  return fs::relative(fs::absolute(target), fs::absolute(from_dir)).generic_string();
}

json Link(const std::string& rel, const std::string& href, const std::string& type) {
  return {{"rel", rel}, {"href", href}, {"type", type}};
}

// An asset for a file that exists: href relative to the document's folder,
// size and SHA-256.
json FileAsset(const fs::path& path, const fs::path& doc_dir, const std::string& media_type,
               const std::vector<std::string>& roles, const std::string& title) {
  return {{"href", Relative(path, doc_dir)},
          {"type", media_type},
          {"roles", roles},
          {"title", title},
          {"file:size", static_cast<long long>(fs::file_size(path))},
          {"file:checksum", Sha256Multihash(Sha256FileHex(path.string()))}};
}

// STAC's name of a GDAL sample type: GDAL's, lower case, but "uint8" for Byte.
std::string StacDataType(GDALDataType type) {
  return type == GDT_Byte ? "uint8" : ToLower(GDALGetDataTypeName(type));
}

// Projection and band fields of a single-band GeoTIFF, read from the file so
// that the catalog says what the file holds.
void AddRasterFields(const fs::path& path, const std::string& unit, json* asset) {
  GDALDatasetH ds = gdal::OpenOrThrow(path.string());
  double gt[6] = {};
  GDALGetGeoTransform(ds, gt);
  const int width = GDALGetRasterXSize(ds), height = GDALGetRasterYSize(ds);
  OGRSpatialReferenceH srs = GDALGetSpatialRef(ds);
  // A compound CRS (UTM + EGM96 height) names its zone on the PROJCS node.
  const char* node = srs && OSRIsCompound(srs) ? "PROJCS" : nullptr;
  const char* code = srs ? OSRGetAuthorityCode(srs, node) : nullptr;
  const char* authority = srs ? OSRGetAuthorityName(srs, node) : nullptr;
  (*asset)["proj:code"] = code && authority ? json(std::string(authority) + ":" + code) : json(nullptr);
  // Heights state their frame in full: the 3D (ellipsoidal) or compound
  // (EGM96) CRS, which the GeoTIFF keys can only partly hold.
  if (const char* item = GDALGetMetadataItem(ds, kHeightReferenceItem, nullptr)) {
    const std::optional<HeightReference> reference = EnumFromName<HeightReference>(item);
    if (reference && *reference != HeightReference::kAboveTerrain && code)
      (*asset)["proj:wkt2"] = HeightCrsWkt(std::atoi(code), reference);
  }
  (*asset)["proj:shape"] = {height, width};
  (*asset)["proj:transform"] = {gt[1], gt[2], gt[0], gt[4], gt[5], gt[3]};
  if (GDALGetRasterCount(ds) > 1) {  // named bands, no statistics
    json bands = json::array();
    for (int b = 1; b <= GDALGetRasterCount(ds); ++b) {
      GDALRasterBandH band = GDALGetRasterBand(ds, b);
      json entry = {{"name", GDALGetDescription(band)},
                    {"data_type", StacDataType(GDALGetRasterDataType(band))}};
      int has_nodata = 0;
      const double nodata = GDALGetRasterNoDataValue(band, &has_nodata);
      if (has_nodata) entry["nodata"] = std::isnan(nodata) ? json("nan") : json(nodata);
      bands.push_back(entry);
    }
    GDALClose(ds);
    (*asset)["bands"] = bands;
    (*asset)["raster:sampling"] = "area";
    (*asset)["raster:spatial_resolution"] = std::abs(gt[1]);
    return;
  }
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  int has_nodata = 0;
  const double nodata = GDALGetRasterNoDataValue(band, &has_nodata);
  // Statistics of the valid cells, computed here (GDAL's own would leave a
  // .aux.xml beside the product).
  std::vector<double> row(static_cast<std::size_t>(width));
  double sum = 0, sum2 = 0, lo = INFINITY, hi = -INFINITY;
  std::size_t valid = 0;
  for (int r = 0; r < height; ++r) {
    if (GDALRasterIO(band, GF_Read, 0, r, width, 1, row.data(), width, 1, GDT_Float64, 0, 0) != CE_None) {
      GDALClose(ds);
      throw Error("stac", path.string(), "cannot read row " + std::to_string(r));
    }
    for (double v : row) {
      if (!std::isfinite(v) || (has_nodata && v == nodata)) continue;
      ++valid;
      sum += v;
      sum2 += v * v;
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  (*asset)["data_type"] = StacDataType(GDALGetRasterDataType(band));
  GDALClose(ds);
  if (has_nodata) (*asset)["nodata"] = std::isnan(nodata) ? json("nan") : json(nodata);
  (*asset)["unit"] = unit;
  (*asset)["raster:sampling"] = "area";
  (*asset)["raster:spatial_resolution"] = std::abs(gt[1]);
  if (valid > 0) {
    const double mean = sum / valid;
    (*asset)["statistics"] = {{"minimum", lo},
                              {"maximum", hi},
                              {"mean", mean},
                              {"stddev", std::sqrt(std::max(0.0, sum2 / valid - mean * mean))},
                              {"valid_percent", 100.0 * valid / (static_cast<double>(width) * height)}};
  }
}

// Adds `path` as asset `key` when the file exists.
void AddIfExists(json* assets, const std::string& key, const fs::path& path, const fs::path& doc_dir,
                 const std::string& media_type, const std::vector<std::string>& roles, const std::string& title) {
  if (fs::exists(path)) (*assets)[key] = FileAsset(path, doc_dir, media_type, roles, title);
}

// A point cloud (`stem` in `dir`, as key `key`) in whichever encoding the
// run wrote, with its CRS (read from the file's WKT record) and 3D bounds.
void AddPointCloud(json* assets, const fs::path& dir, const fs::path& doc_dir, const std::string& stem = "points",
                   const std::string& key = "points", const std::string& what = "the scene's Gaussians") {
  for (const auto& [encoding, name] : EnumNames<PointCloudEncoding>::kNames) {
    const fs::path path = dir / PointCloudFileName(encoding, stem);
    if (!fs::exists(path)) continue;
    json asset = FileAsset(path, doc_dir, PointCloudMediaType(encoding), {"data"},
                           "Point cloud (" + std::string(name) + "): " + what +
                               ", LAS 1.4 format 7, classes 2 ground, 5 high vegetation, 6 building, 1 other");
    const LasHeaderInfo las = ReadLasHeader(path.string());
    OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
    char* wkt_in = const_cast<char*>(las.crs_wkt.c_str());
    if (OSRImportFromWkt(srs, &wkt_in) == OGRERR_NONE) {
      // The horizontal CRS's code: the compound CRS's PROJCS node, or, for an
      // ellipsoidal height (read back as a 3D CRS without a code), the zone's.
      OGRSpatialReferenceH zone = OSRClone(srs);
      if (OSRIsCompound(zone)) {
        OSRStripVertical(zone);
      } else {
        OSRDemoteTo2D(zone, nullptr);
        OSRAutoIdentifyEPSG(zone);
      }
      const char* code = OSRGetAuthorityCode(zone, nullptr);
      const char* authority = OSRGetAuthorityName(zone, nullptr);
      asset["proj:code"] = code && authority ? json(std::string(authority) + ":" + code) : json(nullptr);
      OSRDestroySpatialReference(zone);
      char* wkt2 = nullptr;
      const char* options[] = {"FORMAT=WKT2_2019", nullptr};
      if (OSRExportToWktEx(srs, &wkt2, options) == OGRERR_NONE && wkt2) asset["proj:wkt2"] = wkt2;
      CPLFree(wkt2);
    }
    OSRDestroySpatialReference(srs);
    asset["proj:bbox"] = {las.min_x, las.min_y, las.min_z, las.max_x, las.max_y, las.max_z};
    (*assets)[key] = asset;
  }
}

struct TimeRange {
  std::string start, end;  // empty when no acquisition time is known
};

TimeRange AcquisitionRange(const std::vector<AoiCatalog>& aois) {
  TimeRange range;
  for (const AoiCatalog& a : aois) {
    for (const ImageRecord& im : a.images) {
      if (im.acquisition_time.empty()) continue;
      if (range.start.empty() || im.acquisition_time < range.start) range.start = im.acquisition_time;
      if (range.end.empty() || im.acquisition_time > range.end) range.end = im.acquisition_time;
    }
  }
  return range;
}

// datetime, or start/end when the images span more than one instant.
void AddDatetime(const TimeRange& range, const std::string& fallback, json* properties) {
  if (range.start.empty()) {
    (*properties)["datetime"] = fallback;
  } else if (range.start == range.end) {
    (*properties)["datetime"] = range.start;
  } else {
    (*properties)["datetime"] = nullptr;
    (*properties)["start_datetime"] = range.start;
    (*properties)["end_datetime"] = range.end;
  }
}

using LonLatRing = std::vector<std::array<double, 2>>;

json Polygon(LonLatRing ring) {
  if (ring.front() != ring.back()) ring.push_back(ring.front());
  json coords = json::array();
  for (const auto& p : ring) coords.push_back({p[0], p[1]});
  return {{"type", "Polygon"}, {"coordinates", {coords}}};
}

std::array<double, 4> BoundingBox(const LonLatRing& ring) {
  std::array<double, 4> b{INFINITY, INFINITY, -INFINITY, -INFINITY};
  for (const auto& p : ring) {
    b[0] = std::min(b[0], p[0]);
    b[1] = std::min(b[1], p[1]);
    b[2] = std::max(b[2], p[0]);
    b[3] = std::max(b[3], p[1]);
  }
  return b;
}

LonLatRing AoiRing(const AoiCatalog& a) {
  LonLatRing ring;
  for (const auto& p : a.footprint_lonlat) ring.push_back({p.x(), p.y()});
  return ring;
}

LonLatRing BoxRing(const GroundBox& box, const GeodeticPoint& origin) {
  const EnuFrame frame(origin);
  LonLatRing ring;
  for (const Eigen::Vector2d& c : {box.min_m, Eigen::Vector2d(box.max_m.x(), box.min_m.y()), box.max_m,
                                   Eigen::Vector2d(box.min_m.x(), box.max_m.y())}) {
    const GeodeticPoint g = frame.GeodeticFromEnu(Eigen::Vector3d(c.x(), c.y(), 0.0));
    ring.push_back({g.lon_deg, g.lat_deg});
  }
  return ring;
}

json Item(const std::string& id, const std::string& city, const LonLatRing& ring, json properties, json assets,
          const fs::path& item_path, const fs::path& out_dir, const fs::path& collection_path) {
  const fs::path dir = item_path.parent_path();
  const auto box = BoundingBox(ring);
  // An extension is listed only where its fields are used (the raster
  // schema fails an item that lists it without any raster field).
  json extensions = {kStacFile};
  for (const auto& [key, asset] : assets.items()) {
    if (asset.contains("proj:code")) {
      extensions = {kStacProjection, kStacRaster, kStacFile};
      break;
    }
  }
  return {{"type", "Feature"},
          {"stac_version", kStacVersion},
          {"stac_extensions", extensions},
          {"id", id},
          {"collection", city},
          {"geometry", Polygon(ring)},
          {"bbox", {box[0], box[1], box[2], box[3]}},
          {"properties", std::move(properties)},
          {"assets", std::move(assets)},
          {"links",
           {Link("self", "./" + item_path.filename().string(), kGeoJson),
            Link("root", Relative(out_dir / "catalog.json", dir), kJson),
            Link("parent", Relative(collection_path, dir), kJson),
            Link("collection", Relative(collection_path, dir), kJson)}}};
}

// A COG product as an asset with its projection and bands, when it exists;
// a height raster's title names the reference its heights are measured from.
void AddRaster(json* assets, const std::string& key, const fs::path& path, const fs::path& doc_dir,
               const std::vector<std::string>& roles, const std::string& title, const std::string& unit) {
  if (!fs::exists(path)) return;
  std::string full_title = title;
  if (const std::optional<HeightReference> reference = HeightReferenceOfRaster(path.string()))
    full_title += " (heights above the " + HeightReferenceDescription(*reference) + ")";
  json asset = FileAsset(path, doc_dir, kCog, roles, full_title);
  AddRasterFields(path, unit, &asset);
  if (unit.empty()) asset.erase("unit");
  (*assets)[key] = asset;
}

// The products of one AOI and of its city's scene.
json AoiAssets(const AoiCatalog& a, const StacCity& city, const fs::path& doc_dir) {
  json assets = json::object();
  const fs::path aoi_dir = fs::path(city.out_dir) / a.aoi;
  const fs::path compare = aoi_dir / "dsm_compare";
  AddRaster(&assets, "dsm", aoi_dir / "dsm.tif", doc_dir, {"data"}, "DSM", "m");
  AddRaster(&assets, "dtm", aoi_dir / "dtm.tif", doc_dir, {"data"}, "DTM: bare earth (the dense stage's terrain model)",
            "m");
  AddRaster(&assets, "ndsm", aoi_dir / "ndsm.tif", doc_dir, {"data"}, "nDSM: heights above the DTM", "m");
  AddRaster(&assets, "quality", aoi_dir / "quality.tif", doc_dir, {"data", "metadata"},
            "Quality layers: views, fill rule (codes in the file's FILL_RULE_CODES), matching cost, Gaussian "
            "height spread [m]", "");
  AddRaster(&assets, "ortho", aoi_dir / "ortho.tif", doc_dir, {"data", "visual"},
            "True orthophoto: nadir render of the scene, alpha where empty", "");
  AddRaster(&assets, "classes", aoi_dir / "classes.tif", doc_dir, {"data"},
            "Classes (ASPRS codes, in the file's CLASS_CODES): 2 ground, 5 high vegetation, 6 building, 1 above "
            "ground not told apart", "");
  AddPointCloud(&assets, aoi_dir, doc_dir);
  if (fs::exists(compare / "error_map.tif")) {
    json error = FileAsset(compare / "error_map.tif", doc_dir, kGeoTiff, {"data"}, "DSM minus truth");
    AddRasterFields(compare / "error_map.tif", "m", &error);
    assets["error_map"] = error;
  }
  AddIfExists(&assets, "error_map_png", compare / "error_map.png", doc_dir, kPng, {"overview", "visual"},
              "Error map");
  AddIfExists(&assets, "error_histogram", compare / "error_histogram.png", doc_dir, kPng, {"visual"},
              "Error histogram");
  AddIfExists(&assets, "dsm_report", compare / "report.json", doc_dir, kJson, {"metadata"}, "DSM comparison");
  AddIfExists(&assets, "dsm_report_csv", compare / "report.csv", doc_dir, kCsv, {"metadata"}, "DSM comparison");
  AddIfExists(&assets, "dsm_report_by_class", compare / "report_by_class.csv", doc_dir, kCsv, {"metadata"},
              "DSM error by truth class and along building outlines");
  AddIfExists(&assets, "dsm_report_edge_profile", compare / "report_edge_profile.csv", doc_dir, kCsv, {"metadata"},
              "DSM error by distance from building outlines");
  const fs::path scene = city.scene_dir;
  AddIfExists(&assets, "scene", scene / "scene.ply", doc_dir, kPly, {"data"}, "Gaussian splats (Inria PLY)");
  for (int level = 0; fs::exists(scene / ("lod_" + std::to_string(level) + ".ply")); ++level) {
    AddIfExists(&assets, "lod_" + std::to_string(level), scene / ("lod_" + std::to_string(level) + ".ply"), doc_dir,
                kPly, {"data"}, "Level of detail " + std::to_string(level));
  }
  AddIfExists(&assets, "lod", scene / "lod.json", doc_dir, kJson, {"metadata"}, "Levels of detail");
  AddIfExists(&assets, "run_report", city.run_report, doc_dir, kJson, {"metadata"}, "Run report of the city");
  return assets;
}

json TileAssets(const fs::path& tile_dir, const fs::path& doc_dir) {
  json assets = json::object();
  const std::string scene = TileScenePath(tile_dir.string());
  AddIfExists(&assets, "scene", scene, doc_dir, kPly, {"data"}, "Gaussian splats of the tile (Inria PLY)");
  AddIfExists(&assets, "dense", tile_dir / "sfm" / "dense.ply", doc_dir, kPly, {"data"}, "Dense heights (PLY)");
  AddIfExists(&assets, "tile_report", tile_dir / "tile_report.json", doc_dir, kJson, {"metadata"}, "Tile report");
  AddIfExists(&assets, "tile", tile_dir / "tile.json", doc_dir, kJson, {"metadata"}, "Tile definition");
  return assets;
}

void WriteDoc(const fs::path& path, const json& doc) { WriteFileIfChanged(path.string(), doc.dump(2) + "\n"); }

}  // namespace

std::string WriteCityStac(const StacCity& city) {
  gdal::EnsureRegistered();
  const fs::path out(city.out_dir);
  const fs::path collection_path = out / city.city / "collection.json";
  const TimeRange times = AcquisitionRange(city.aois);
  const std::string fallback = city.processed_utc.empty() ? UtcNowIso() : city.processed_utc;
  json item_links = json::array();
  LonLatRing all;
  json codes = json::array();
  for (const AoiCatalog& a : city.aois) {
    const fs::path item_path = out / a.aoi / (a.aoi + ".json");
    json properties = {{"title", a.aoi}};
    AddDatetime(AcquisitionRange({a}), fallback, &properties);
    const LonLatRing ring = AoiRing(a);
    all.insert(all.end(), ring.begin(), ring.end());
    const std::string code = "EPSG:" + std::to_string(a.epsg);
    if (std::find(codes.begin(), codes.end(), json(code)) == codes.end()) codes.push_back(code);
    WriteDoc(item_path, Item(a.aoi, city.city, ring, properties, AoiAssets(a, city, item_path.parent_path()),
                             item_path, out, collection_path));
    item_links.push_back(Link("item", Relative(item_path, collection_path.parent_path()), kGeoJson));
  }
  for (const std::string& dir : city.tile_dirs) {
    if (!fs::exists(fs::path(dir) / "tile_report.json")) continue;
    const TileSpec spec = ReadTileSpec((fs::path(dir) / "tile.json").string());
    const fs::path item_path = fs::path(dir) / (spec.id + ".json");
    json properties = {{"title", "tile " + spec.id}};
    AddDatetime(times, fallback, &properties);
    WriteDoc(item_path, Item(spec.id, city.city, BoxRing(spec.extent, spec.enu_origin), properties,
                             TileAssets(dir, item_path.parent_path()), item_path, out, collection_path));
    item_links.push_back(Link("item", Relative(item_path, collection_path.parent_path()), kGeoJson));
  }
  const auto box = BoundingBox(all);
  // The city's own layers: its DSM and, for a city of several AOIs, the
  // mosaics of their orthophotos, DTMs, quality layers and classes.
  json assets = json::object();
  const fs::path city_dir = out / city.city;
  AddRaster(&assets, "dsm_city", city_dir / "scene" / "dsm_city.tif", city_dir, {"data"},
            "City DSM: the merged scene's heights over every AOI", "m");
  AddRaster(&assets, "ortho_city", city_dir / "ortho_city.tif", city_dir, {"data", "visual"},
            "City orthophoto: the AOIs' true orthophotos in one mosaic", "");
  AddRaster(&assets, "dtm_city", city_dir / "dtm_city.tif", city_dir, {"data"}, "City DTM: bare earth", "m");
  AddRaster(&assets, "quality_city", city_dir / "quality_city.tif", city_dir, {"data", "metadata"},
            "City quality layers (as each AOI's quality.tif)", "");
  AddRaster(&assets, "classes_city", city_dir / "classes_city.tif", city_dir, {"data"},
            "City classes (ASPRS codes, as each AOI's classes.tif)", "");
  AddPointCloud(&assets, city_dir, city_dir, "points_city", "points_city", "the city's Gaussians over every AOI");
  json links = {Link("self", "./collection.json", kJson), Link("root", "../catalog.json", kJson),
                Link("parent", "../catalog.json", kJson)};
  for (const json& l : item_links) links.push_back(l);
  json collection = {
      {"type", "Collection"},
      {"stac_version", kStacVersion},
      {"stac_extensions", assets.empty() ? json{kStacProjection, kStacFile}
                                         : json{kStacProjection, kStacRaster, kStacFile}},
      {"id", city.city},
      {"title", "City " + city.city},
      {"description", "3D Gaussian-splat city scene, level of detail and DSM products reconstructed by skyfall "
                      "from multi-view satellite imagery of " + std::to_string(city.aois.size()) + " AOI(s)"},
      {"license", "other"},
      {"providers", {{{"name", "skyfall"}, {"roles", {"processor"}}, {"description", "skyfall tiler"}}}},
      {"extent",
       {{"spatial", {{"bbox", {{box[0], box[1], box[2], box[3]}}}}},
        {"temporal", {{"interval", json::array({json::array({times.start.empty() ? fallback : times.start,
                                                             times.end.empty() ? fallback : times.end})})}}}}},
      {"summaries", {{"proj:code", codes}}},
      {"links", links}};
  if (!assets.empty()) collection["assets"] = assets;
  WriteDoc(collection_path, collection);
  return collection_path.string();
}

std::string WriteRootStacCatalog(const std::string& out_dir) {
  const fs::path out(out_dir);
  std::vector<std::string> children;
  for (const auto& entry : fs::directory_iterator(out)) {
    if (entry.is_directory() && fs::exists(entry.path() / "collection.json")) {
      children.push_back(entry.path().filename().string() + "/collection.json");
    }
  }
  std::sort(children.begin(), children.end());
  json links = {Link("self", "./catalog.json", kJson), Link("root", "./catalog.json", kJson)};
  for (const std::string& c : children) links.push_back(Link("child", "./" + c, kJson));
  const json catalog = {{"type", "Catalog"},
                        {"stac_version", kStacVersion},
                        {"id", out.filename().empty() ? "skyfall" : out.filename().string()},
                        {"title", "skyfall products"},
                        {"description", "Cities reconstructed by skyfall: scenes, levels of detail and DSMs"},
                        {"links", links}};
  const fs::path path = out / "catalog.json";
  WriteDoc(path, catalog);
  return path.string();
}

}  // namespace skyfall
