#include "tiling/tiling.h"

#include <gdal_utils.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <limits>
#include <set>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "catalogs/aoi_catalog.h"
#include "catalogs/tile_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/ground_cell.h"
#include "ingest/gdal_util.h"
#include "ingest/geo.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

// A city wider than a whole number of tiles by less than this fraction of a
// tile gets no extra column or row: a UTM-aligned AOI seen in the ENU frame is
// rotated by the grid convergence (0.33 deg at JAX_068), which widens its
// bounding box by ~1.5 m per 256 m. The edge cores own everything beyond them.
constexpr double kGridSlackFraction = 0.05;
// Pixels added around a crop window: WorldView-3 RPCs carry pointing biases
// of up to a few tens of pixels (measured 37 px on JAX_068), which the tile's
// bundle adjustment absorbs only if the content is inside the crop.
constexpr int kCropPadPx = 48;

std::string CityName(const TilingOptions& options, const std::vector<AoiCatalog>& aois) {
  if (!options.city.empty()) return options.city;
  if (aois.size() == 1) return aois[0].aoi;
  std::string prefix = aois[0].aoi;
  for (const AoiCatalog& a : aois) {
    std::size_t k = 0;
    while (k < prefix.size() && k < a.aoi.size() && prefix[k] == a.aoi[k]) ++k;
    prefix.resize(k);
  }
  const std::size_t cut = prefix.find_last_of('_');
  if (cut != std::string::npos && cut > 0) prefix.resize(cut);
  while (!prefix.empty() && (prefix.back() == '_' || prefix.back() == '-')) prefix.pop_back();
  return prefix.empty() ? "city" : prefix;
}

GeodeticPoint SharedOrigin(const std::vector<AoiCatalog>& aois) {
  if (aois.size() == 1) return aois[0].enu_origin;
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  double height = 0;
  for (const AoiCatalog& a : aois) {
    for (const auto& p : a.footprint_lonlat) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    height += a.enu_origin.height_m / aois.size();
  }
  return {0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), height};
}

GroundBox FootprintBounds(const EnuFrame& frame, const std::vector<AoiCatalog>& aois) {
  GroundBox b;
  b.min_m = Eigen::Vector2d(1e18, 1e18);
  b.max_m = -b.min_m;
  for (const AoiCatalog& a : aois) {
    for (const auto& p : a.footprint_lonlat) {
      const Eigen::Vector3d enu = frame.EnuFromGeodetic({p.x(), p.y(), frame.origin().height_m});
      b.min_m = b.min_m.cwiseMin(enu.head<2>());
      b.max_m = b.max_m.cwiseMax(enu.head<2>());
    }
  }
  return b;
}

GroundBox Intersect(const GroundBox& a, const GroundBox& b) {
  GroundBox r;
  r.min_m = a.min_m.cwiseMax(b.min_m);
  r.max_m = a.max_m.cwiseMin(b.max_m);
  return r;
}

// Where the tile's 3D box (extent x height range) lands in an image: the
// bounding rectangle of its 8 projected corners, in pixel-centre coordinates.
struct Footprint {
  Eigen::Vector2d lo_px, hi_px;
};

Footprint ProjectBox(const EnuFrame& frame, const GroundBox& box, double h0, double h1, const RpcModel& rpc) {
  Footprint f{Eigen::Vector2d(1e18, 1e18), Eigen::Vector2d(-1e18, -1e18)};
  for (int corner = 0; corner < 4; ++corner) {
    const double e = (corner & 1) ? box.max_m.x() : box.min_m.x();
    const double n = (corner & 2) ? box.max_m.y() : box.min_m.y();
    const GeodeticPoint g = frame.GeodeticFromEnu({e, n, 0.0});
    for (double h : {h0, h1}) {
      const Eigen::Vector2d px = rpc.Project(g.lon_deg, g.lat_deg, h);
      f.lo_px = f.lo_px.cwiseMin(px);
      f.hi_px = f.hi_px.cwiseMax(px);
    }
  }
  return f;
}

// Fraction of the projected rectangle inside the image's pixel area.
double Coverage(const Footprint& f, int width_px, int height_px) {
  const Eigen::Vector2d edge_lo = f.lo_px.array() - 0.5, edge_hi = f.hi_px.array() + 0.5;
  const double area = (edge_hi - edge_lo).prod();
  const double w = std::min(edge_hi.x(), width_px - 0.5) - std::max(edge_lo.x(), -0.5);
  const double h = std::min(edge_hi.y(), height_px - 0.5) - std::max(edge_lo.y(), -0.5);
  return (w <= 0 || h <= 0 || area <= 0) ? 0.0 : w * h / area;
}

void SelectImages(const TilingOptions& options, const EnuFrame& frame, const std::vector<AoiCatalog>& aois,
                  TileSpec* tile, AoiCatalog* catalog) {
  for (const AoiCatalog& aoi : aois) {
    for (const ImageRecord& im : aoi.images) {
      const bool seen = std::any_of(tile->images.begin(), tile->images.end(),
                                    [&](const TileImage& t) { return t.name == im.name; });
      if (seen) continue;
      const Footprint f = ProjectBox(frame, tile->extent, tile->min_ellipsoid_height_m, tile->max_ellipsoid_height_m, im.rpc);
      const double coverage = Coverage(f, im.width_px, im.height_px);
      if (coverage < options.min_coverage) continue;
      TileImage t;
      t.name = im.name;
      t.source_path = im.path;
      t.coverage = coverage;
      t.col0_px = std::max(0, static_cast<int>(std::floor(f.lo_px.x())) - kCropPadPx);
      t.row0_px = std::max(0, static_cast<int>(std::floor(f.lo_px.y())) - kCropPadPx);
      const int col1 = std::min(im.width_px, static_cast<int>(std::ceil(f.hi_px.x())) + 1 + kCropPadPx);
      const int row1 = std::min(im.height_px, static_cast<int>(std::ceil(f.hi_px.y())) + 1 + kCropPadPx);
      t.width_px = col1 - t.col0_px;
      t.height_px = row1 - t.row0_px;
      tile->images.push_back(t);

      ImageRecord crop = im;
      crop.width_px = t.width_px;
      crop.height_px = t.height_px;
      crop.rpc = im.rpc.Cropped(t.col0_px, t.row0_px);
      catalog->images.push_back(crop);
      auto in = [&](const std::vector<std::string>& v) { return std::find(v.begin(), v.end(), im.name) != v.end(); };
      if (in(aoi.train_images)) catalog->train_images.push_back(im.name);
      if (in(aoi.test_images)) catalog->test_images.push_back(im.name);
    }
  }
}

AoiCatalog TileCatalog(const AoiCatalog& first, const TileSpec& tile, const EnuFrame& frame) {
  AoiCatalog c;
  c.aoi = tile.id;
  c.source_root = first.source_root;
  c.enu_origin = tile.enu_origin;
  c.utm_zone = first.utm_zone;
  c.utm_north = first.utm_north;
  c.epsg = first.epsg;
  for (int k = 0; k < 4; ++k) {
    const double e = (k == 1 || k == 2) ? tile.extent.max_m.x() : tile.extent.min_m.x();
    const double n = (k >= 2) ? tile.extent.max_m.y() : tile.extent.min_m.y();
    const GeodeticPoint g = frame.GeodeticFromEnu({e, n, 0.0});
    c.footprint_lonlat.emplace_back(g.lon_deg, g.lat_deg);
  }
  c.footprint_source = "tile_extent";
  c.min_ellipsoid_height_m = tile.min_ellipsoid_height_m;
  c.max_ellipsoid_height_m = tile.max_ellipsoid_height_m;
  c.height_range_source = first.height_range_source;
  return c;
}

}  // namespace

void TilingOptions::Check() const {
  CheckOptionRanges(*this, "tile");
  if (!(tile_m == 0.0 || overlap_m < tile_m)) {
    throw Error("tile", "overlap_m", "must be in [0, tile_m), got " + std::to_string(overlap_m));
  }
}

double ImageGroundSampleM(const ImageRecord& image, double ellipsoid_height_m) {
  const double c = 0.5 * (image.width_px - 1), r = 0.5 * (image.height_px - 1);
  const Eigen::Vector2d o = Localize(image.rpc, c, r, ellipsoid_height_m);
  const EnuFrame frame({o.x(), o.y(), ellipsoid_height_m});
  auto ground = [&](double dc, double dr) -> Eigen::Vector2d {  // a value: head<2>() of a temporary dangles
    const Eigen::Vector2d ll = Localize(image.rpc, c + dc, r + dr, ellipsoid_height_m);
    return frame.EnuFromGeodetic({ll.x(), ll.y(), ellipsoid_height_m}).head<2>();
  };
  // Over 10 px, so that round-off of the localization does not show.
  const Eigen::Vector2d along_col = ground(10, 0) / 10.0, along_row = ground(0, 10) / 10.0;
  return std::sqrt(std::abs(along_col.x() * along_row.y() - along_col.y() * along_row.x()));
}

double ChooseTileSideM(const TilingOptions& options, const std::vector<AoiCatalog>& aois, double* finest_gsd_m) {
  double finest = std::numeric_limits<double>::infinity();
  for (const AoiCatalog& a : aois) {
    const double mid_m = 0.5 * (a.min_ellipsoid_height_m + a.max_ellipsoid_height_m);
    for (const ImageRecord& im : a.images) finest = std::min(finest, ImageGroundSampleM(im, mid_m));
  }
  if (finest_gsd_m) *finest_gsd_m = std::isfinite(finest) ? finest : 0.0;
  if (options.tile_m > 0) return options.tile_m;
  if (!std::isfinite(finest)) return kAutoTileStepM;
  const double steps = std::max(1.0, std::round(options.tile_cells * DenseCellForGsdM(finest) / kAutoTileStepM));
  return steps * kAutoTileStepM;
}

std::string TileId(const std::string& city, int col, int row) {
  return city + "_c" + std::to_string(col) + "_r" + std::to_string(row);
}

TilePlan PlanTiles(const TilingOptions& options, const std::vector<AoiCatalog>& aois) {
  options.Check();
  if (aois.empty()) throw Error("tile", "", "no AOI given");
  for (const AoiCatalog& a : aois) {
    if (a.images.empty()) throw Error("tile", a.aoi, "the AOI has no images (empty AOI)");
    if (a.footprint_lonlat.size() < 3) throw Error("tile", a.aoi, "the AOI has no footprint (empty AOI)");
    if (a.epsg != aois[0].epsg) {
      throw Error("tile", a.aoi, "UTM EPSG " + std::to_string(a.epsg) + " differs from " + aois[0].aoi + "'s " +
                                     std::to_string(aois[0].epsg) + ": AOIs of one city must share a zone");
    }
  }
  TilePlan plan;
  plan.city = CityName(options, aois);
  plan.enu_origin = SharedOrigin(aois);
  const EnuFrame frame(plan.enu_origin);
  plan.bounds = FootprintBounds(frame, aois);
  if (!(plan.bounds.Width() > 0 && plan.bounds.Height() > 0)) throw Error("tile", plan.city, "empty AOI footprint");

  TileGrid& g = plan.grid;
  g.tile_m = ChooseTileSideM(options, aois, &plan.finest_gsd_m);
  plan.tile_side_automatic = options.tile_m == 0;
  if (!(options.overlap_m < g.tile_m)) {
    throw Error("tile", "overlap_m", "must be below the tile side " + std::to_string(g.tile_m) + " m, got " +
                                         std::to_string(options.overlap_m));
  }
  g.overlap_m = options.overlap_m;
  g.cols = std::max(1, static_cast<int>(std::ceil(plan.bounds.Width() / g.tile_m - kGridSlackFraction)));
  g.rows = std::max(1, static_cast<int>(std::ceil(plan.bounds.Height() / g.tile_m - kGridSlackFraction)));
  const Eigen::Vector2d centre = 0.5 * (plan.bounds.min_m + plan.bounds.max_m);
  g.origin_m = centre - 0.5 * g.tile_m * Eigen::Vector2d(g.cols, g.rows);

  double min_h = 1e18, max_h = -1e18;
  for (const AoiCatalog& a : aois) {
    min_h = std::min(min_h, a.min_ellipsoid_height_m);
    max_h = std::max(max_h, a.max_ellipsoid_height_m);
  }
  // The margin reaches beyond the city's bounds too: what stands just
  // outside (a tower hiding roofs and streets inside from some views) is
  // reconstructed rather than left for training to explain with the roofs it
  // hides. Outer sides start from the bounds, so that a one-tile city's
  // cells keep the bounds' lattice.
  GroundBox reach = plan.bounds;
  reach.min_m.array() -= g.overlap_m;
  reach.max_m.array() += g.overlap_m;
  for (int row = 0; row < g.rows; ++row) {
    for (int col = 0; col < g.cols; ++col) {
      TileSpec t;
      t.id = TileId(plan.city, col, row);
      t.city = plan.city;
      for (const AoiCatalog& a : aois) t.aois.push_back(a.aoi);
      t.col = col;
      t.row = row;
      t.grid = g;
      t.core = g.Core(col, row);
      GroundBox grown = t.core;
      grown.min_m.array() -= g.overlap_m;
      grown.max_m.array() += g.overlap_m;
      if (col == 0) grown.min_m.x() = reach.min_m.x();
      if (row == 0) grown.min_m.y() = reach.min_m.y();
      if (col == g.cols - 1) grown.max_m.x() = reach.max_m.x();
      if (row == g.rows - 1) grown.max_m.y() = reach.max_m.y();
      t.extent = Intersect(grown, reach);
      t.enu_origin = plan.enu_origin;
      t.min_ellipsoid_height_m = min_h;
      t.max_ellipsoid_height_m = max_h;
      AoiCatalog catalog = TileCatalog(aois[0], t, frame);
      SelectImages(options, frame, aois, &t, &catalog);
      if (static_cast<int>(t.images.size()) < options.min_images) {
        t.images.clear();  // nothing to reconstruct: the tile stays, empty
        catalog.images.clear();
        catalog.train_images.clear();
        catalog.test_images.clear();
      }
      plan.tiles.push_back(std::move(t));
      plan.catalogs.push_back(std::move(catalog));
    }
  }
  AssignGaugeAcquisitions(&plan);
  return plan;
}

void AssignGaugeAcquisitions(TilePlan* plan) {
  const auto with_images = std::count_if(plan->catalogs.begin(), plan->catalogs.end(),
                                         [](const AoiCatalog& c) { return !c.images.empty(); });
  std::vector<std::set<std::string>> held;  // per tile with images: its acquisitions
  for (const AoiCatalog& c : plan->catalogs) {
    if (c.images.empty()) continue;
    std::set<std::string> times;
    for (const ImageRecord& im : c.images) {
      if (im.acquisition_time.empty()) {
        plan->gauge = "each tile: the average of its images' RPCs (" + im.name +
                      " has no acquisition time, so the acquisitions the tiles share are unknown)";
        plan->gauge_shared = with_images <= 1;
        return;
      }
      times.insert(im.acquisition_time);
    }
    held.push_back(std::move(times));
  }
  if (held.empty()) {
    plan->gauge = "no tile has images";
    return;
  }
  std::set<std::string> common = held[0];
  bool all_equal = true;
  for (const auto& h : held) {
    all_equal = all_equal && h == held[0];
    std::set<std::string> both;
    std::set_intersection(common.begin(), common.end(), h.begin(), h.end(), std::inserter(both, both.end()));
    common = std::move(both);
  }
  if (all_equal) {
    plan->gauge = fmt::format("every tile: the average of the same {} acquisitions' RPCs", common.size());
    return;
  }
  if (common.size() < 2) {
    plan->gauge_shared = false;
    plan->gauge = fmt::format(
        "each tile: the average of its own images' RPCs; the tiles hold different acquisitions and {} in common, "
        "so their frames differ by the RPCs' biases and the city may step at tile borders",
        common.size());
    return;
  }
  const std::vector<std::string> gauge(common.begin(), common.end());
  for (AoiCatalog& c : plan->catalogs)
    if (!c.images.empty()) c.gauge_acquisitions = gauge;
  plan->gauge = fmt::format("every tile: the average of the RPCs of the {} acquisitions all {} tiles hold", gauge.size(),
                            held.size());
}

namespace {

// A VRT window of `source`, written beside `path` and renamed over it only
// when it differs from what is there.
void WriteCropVrt(const TileImage& im, const std::string& path) {
  gdal::EnsureRegistered();
  gdal::QuietErrors quiet;
  gdal::Dataset src(gdal::OpenOrThrow(im.source_path));
  const std::string tmp = path + ".tmp.vrt";
  std::vector<std::string> args = {"-of", "VRT", "-srcwin", std::to_string(im.col0_px), std::to_string(im.row0_px),
                                   std::to_string(im.width_px), std::to_string(im.height_px)};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  GDALTranslateOptions* opts = GDALTranslateOptionsNew(argv.data(), nullptr);
  int usage_error = 0;
  GDALDatasetH out = GDALTranslate(tmp.c_str(), src.handle, opts, &usage_error);
  GDALTranslateOptionsFree(opts);
  if (!out) throw Error("tile", im.source_path, "cannot write the crop window VRT " + tmp + ": " + quiet.LastMessage());
  GDALClose(out);
  const std::string text = ReadTextFile(tmp);
  fs::remove(tmp);
  WriteFileIfChanged(path, text);
}

nlohmann::json IndexJson(const TilePlan& plan) {
  nlohmann::json tiles = nlohmann::json::array();
  for (const TileSpec& t : plan.tiles) {
    tiles.push_back({{"id", t.id}, {"col", t.col}, {"row", t.row}, {"images", t.images.size()},
                     {"status", t.images.empty() ? "no_images" : "ok"}});
  }
  return {{"schema", "skyfall.tiles/1"},
          {"city", plan.city},
          {"enu_origin", {{"lon_deg", plan.enu_origin.lon_deg}, {"lat_deg", plan.enu_origin.lat_deg},
                          {"height_m", plan.enu_origin.height_m}}},
          {"bounds", BoxToJson(plan.bounds)},
          {"grid", {{"cols", plan.grid.cols}, {"rows", plan.grid.rows}, {"tile_m", plan.grid.tile_m},
                    {"overlap_m", plan.grid.overlap_m}, {"tile_side", plan.tile_side_automatic ? "auto" : "option"},
                    {"finest_gsd_m", plan.finest_gsd_m}}},
          {"gauge", plan.gauge},
          {"tiles", tiles}};
}

}  // namespace

TilingResult WriteTiles(const TilePlan& plan, const std::string& out_dir, Progress& progress) {
  Stopwatch clock;
  TilingResult result;
  result.plan = plan;
  result.report.stage = "tile";
  progress.Begin("tile " + plan.city, plan.tiles.size());
  int crops = 0, empty = 0;
  for (std::size_t k = 0; k < plan.tiles.size(); ++k) {
    TileSpec& tile = result.plan.tiles[k];
    AoiCatalog& catalog = result.plan.catalogs[k];
    const fs::path dir = fs::absolute(fs::path(out_dir) / tile.id);
    fs::create_directories(dir / "crops");
    for (std::size_t i = 0; i < tile.images.size(); ++i) {
      tile.images[i].crop_path = (dir / "crops" / (tile.images[i].name + ".vrt")).string();
      WriteCropVrt(tile.images[i], tile.images[i].crop_path);
      catalog.images[i].path = tile.images[i].crop_path;
      ++crops;
    }
    if (tile.images.empty()) {
      ++empty;
      progress.Warn("tile " + tile.id + ": fewer than 2 images see it; it will be skipped");
    }
    WriteFileIfChanged((dir / "tile.json").string(), TileSpecToJson(tile));
    WriteFileIfChanged((dir / "aoi.json").string(), AoiCatalogToJson(catalog));
    result.tile_dirs.push_back(dir.string());
    progress.Advance(k + 1, tile.id);
  }
  progress.End();
  WriteFileIfChanged((fs::path(out_dir) / "tiles.json").string(), IndexJson(result.plan).dump(2) + "\n");
  result.report.metrics = {{"tiles", static_cast<double>(plan.tiles.size())},
                           {"tiles_without_images", static_cast<double>(empty)},
                           {"crops", static_cast<double>(crops)},
                           {"tile_m", plan.grid.tile_m},
                           {"finest_gsd_m", plan.finest_gsd_m}};
  result.report.seconds = clock.Seconds();
  return result;
}

}  // namespace skyfall
