#include "products/viewer.h"

#include <cpl_conv.h>
#include <gdal.h>
#include <gdalwarper.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "products/report_page.h"
#include "ingest/gdal_util.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Height -> colour: a blue-green-yellow-white ramp (low to high), t in [0, 1].
std::array<std::uint8_t, 3> Ramp(double t) {
  static constexpr double kStops[5][3] = {{40, 60, 140}, {40, 140, 120}, {140, 190, 60}, {240, 220, 90}, {255, 255, 255}};
  t = std::clamp(t, 0.0, 1.0) * 4.0;
  const int i = std::min(3, static_cast<int>(t));
  const double f = t - i;
  std::array<std::uint8_t, 3> c{};
  for (int k = 0; k < 3; ++k) c[k] = static_cast<std::uint8_t>(std::lround(kStops[i][k] * (1 - f) + kStops[i + 1][k] * f));
  return c;
}

std::string FirstCityWithTileset(const fs::path& out) {
  std::vector<std::string> cities;
  for (const auto& entry : fs::directory_iterator(out)) {
    if (fs::exists(entry.path() / "3dtiles" / "tileset.json")) cities.push_back(entry.path().filename().string());
  }
  std::sort(cities.begin(), cities.end());
  if (cities.empty()) {
    throw Error("view", out.string(), "holds no 3D Tiles (run with --3dtiles, or skyfall export 3dtiles)");
  }
  return cities.front();
}

// The page: CesiumJS with no base imagery and no ion services, the DSM as the
// ground, the tileset, the camera on the city; window.skyfallStatus tells
// scripts (and the browser test) when every tile is loaded and what failed.
std::string IndexHtml(const std::string& city, const GroundImage& ground) {
  const json config = {{"city", city},
                       {"ground_height_m", ground.low_height_m},
                       {"tileset", "../" + city + "/3dtiles/tileset.json"},
                       {"ground", "ground.png"},
                       {"rectangle_deg", {ground.west_deg, ground.south_deg, ground.east_deg, ground.north_deg}}};
  return R"(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>skyfall: )" + HtmlEscape(city) + R"(</title>
<script>window.CESIUM_BASE_URL = "cesium/";</script>
<script src="cesium/Cesium.js"></script>
<link href="cesium/Widgets/widgets.css" rel="stylesheet">
<style>html, body, #map { width: 100%; height: 100%; margin: 0; overflow: hidden; }
#info { position: absolute; top: 8px; left: 8px; background: rgba(0,0,0,.6); color: #fff; padding: 4px 8px;
font: 13px system-ui, sans-serif; border-radius: 4px; }</style></head>
<body><div id="map"></div><div id="info"><span id="state">)" + HtmlEscape(city) + R"(: loading…</span>
<label><input type="checkbox" id="dsm"> DSM under the city</label></div>
<script>
const config = )" + config.dump() + R"(;
window.skyfallStatus = { loaded: false, errors: [] };
window.addEventListener("error", (e) => window.skyfallStatus.errors.push(String(e.message)));
(async () => {
  try {
    const viewer = new Cesium.Viewer("map", {
      baseLayer: false, baseLayerPicker: false, geocoder: false, timeline: false, animation: false,
      sceneModePicker: false, navigationHelpButton: false, homeButton: false, fullscreenButton: false,
      infoBox: false, selectionIndicator: false,
      terrainProvider: new Cesium.EllipsoidTerrainProvider(),
    });
    viewer.scene.globe.baseColor = Cesium.Color.fromCssColorString("#303438");
    // The city lies near the ellipsoid: draw it whether above or below it.
    viewer.scene.globe.depthTestAgainstTerrain = false;
    // The DSM as a coloured rectangle just below the city's lowest heights
    // (an imagery layer would lie on the ellipsoid, metres away from it),
    // off until the checkbox turns it on: its height colours show through
    // the translucent splats. Drawn in the opaque pass: as a translucent
    // primitive it was sorted over the splats and hid the whole city.
    const r = config.rectangle_deg;
    const dsm = viewer.entities.add({ show: false, rectangle: {
      coordinates: Cesium.Rectangle.fromDegrees(r[0], r[1], r[2], r[3]),
      height: config.ground_height_m,
      material: new Cesium.ImageMaterialProperty({ image: config.ground, transparent: false }) } });
    document.getElementById("dsm").addEventListener("change", (e) => { dsm.show = e.target.checked; });
    // A level's geometricError is the farthest any finest Gaussian lies from
    // its merged stand-in (2.9 m for the 2 m level of the 1 km city): at
    // Cesium's default of 16 px the whole city showed as a haze and a street
    // seen from 150 m kept that level. At 4 px the finest level comes within
    // about 500 m (decision D-146).
    const tileset = await Cesium.Cesium3DTileset.fromUrl(config.tileset, { maximumScreenSpaceError: 4 });
    viewer.scene.primitives.add(tileset);
    tileset.tileFailed.addEventListener((e) => window.skyfallStatus.errors.push("tile " + e.url + ": " + e.message));
    tileset.allTilesLoaded.addEventListener(() => {
      window.skyfallStatus.loaded = true;
      window.skyfallStatus.tilesLoaded = tileset.tilesLoaded;
      document.getElementById("state").textContent = config.city + ": all visible tiles loaded";
    });
    window.skyfallView = { viewer, tileset };  // for scripts that move the camera (web/check_city_view.mjs)
    const sphere = tileset.boundingSphere;
    viewer.camera.viewBoundingSphere(sphere,
      new Cesium.HeadingPitchRange(0.3, Cesium.Math.toRadians(-45), sphere.radius * 2.2));
    viewer.camera.lookAtTransform(Cesium.Matrix4.IDENTITY);
  } catch (e) {
    window.skyfallStatus.errors.push(String(e && e.message || e));
    document.getElementById("state").textContent = "error: " + e;
  }
})();
</script></body></html>
)";
}

}  // namespace

GroundImage WriteGroundPng(const std::string& dsm_tif, const std::string& png) {
  gdal::EnsureRegistered();
  GDALDatasetH src = gdal::OpenOrThrow(dsm_tif);
  OGRSpatialReferenceH wgs84 = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(wgs84, 4326);
  OSRSetAxisMappingStrategy(wgs84, OAMS_TRADITIONAL_GIS_ORDER);  // lon, lat
  char* wkt = nullptr;
  OSRExportToWkt(wgs84, &wkt);
  GDALDatasetH warped = GDALAutoCreateWarpedVRT(src, nullptr, wkt, GRA_Bilinear, 0.125, nullptr);
  CPLFree(wkt);
  OSRDestroySpatialReference(wgs84);
  if (!warped) {
    GDALClose(src);
    throw Error("view", dsm_tif, "cannot warp the DSM to WGS84");
  }
  const int w = GDALGetRasterXSize(warped), h = GDALGetRasterYSize(warped);
  std::vector<float> heights(static_cast<std::size_t>(w) * h);
  const CPLErr read = GDALRasterIO(GDALGetRasterBand(warped, 1), GF_Read, 0, 0, w, h, heights.data(), w, h,
                                   GDT_Float32, 0, 0);
  double gt[6] = {};
  GDALGetGeoTransform(warped, gt);
  int has_nodata = 0;
  const double nodata = GDALGetRasterNoDataValue(GDALGetRasterBand(src, 1), &has_nodata);
  GDALClose(warped);
  GDALClose(src);
  if (read != CE_None) throw Error("view", dsm_tif, "cannot read the warped DSM");
  auto valid = [&](float v) { return std::isfinite(v) && !(has_nodata && v == nodata); };
  std::vector<float> sorted;
  for (float v : heights) {
    if (valid(v)) sorted.push_back(v);
  }
  if (sorted.empty()) throw Error("view", dsm_tif, "holds no height");
  std::sort(sorted.begin(), sorted.end());
  // 2..98 % of the heights span the ramp, so a few outliers do not flatten it.
  const double lo = sorted[sorted.size() * 2 / 100], hi = std::max(lo + 1.0, double(sorted[sorted.size() * 98 / 100]));
  std::vector<std::uint8_t> rgba(heights.size() * 4, 0);
  for (std::size_t k = 0; k < heights.size(); ++k) {
    if (!valid(heights[k])) continue;
    const auto c = Ramp((heights[k] - lo) / (hi - lo));
    std::copy(c.begin(), c.end(), rgba.begin() + 4 * k);
    rgba[4 * k + 3] = 255;
  }
  WriteBytePng(png, w, h, 4, rgba.data());
  return {gt[0], gt[3] + h * gt[5], gt[0] + w * gt[1], gt[3], sorted.front() - 0.5};
}

ViewPage WriteViewPage(const std::string& out_dir, const std::string& city_name, const std::string& cesium_dir) {
  const fs::path out(out_dir);
  if (!fs::is_directory(out)) throw Error("view", out_dir, "is not a folder");
  const std::string city = city_name.empty() ? FirstCityWithTileset(out) : city_name;
  if (!fs::exists(out / city / "3dtiles" / "tileset.json")) {
    throw Error("view", (out / city / "3dtiles" / "tileset.json").string(),
                "is missing (run with --3dtiles, or skyfall export 3dtiles)");
  }
  if (!fs::exists(fs::path(cesium_dir) / "Cesium.js")) {
    throw Error("view", cesium_dir, "holds no Cesium.js (scripts/setup.sh installs CesiumJS into web/node_modules)");
  }
  const fs::path view = out / "view";
  fs::create_directories(view);
  const auto ground = WriteGroundPng((out / city / "scene" / "dsm_city.tif").string(), (view / "ground.png").string());
  const fs::path link = view / "cesium";
  std::error_code ec;
  fs::remove(link, ec);
  fs::create_directory_symlink(fs::absolute(cesium_dir), link, ec);
  if (ec) throw Error("view", link.string(), "cannot link CesiumJS: " + ec.message());
  ViewPage page{city, (view / "index.html").string(), "view/index.html"};
  WriteFileAtomic(page.index_html, IndexHtml(city, ground));
  return page;
}

}  // namespace skyfall
