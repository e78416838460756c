// `skyfall view OUT`: a CesiumJS page over a run's 3D Tiles, served on
// localhost. CesiumJS comes from the project's npm install (web/), so the
// page needs no network, imagery provider or ion token: the ground under
// the city is the city's DSM, coloured by height and warped to WGS84, as one
// image (off until the page's checkbox turns it on).
#pragma once

#include <string>

namespace skyfall {

struct ViewPage {
  std::string city;
  std::string index_html;   // OUT/view/index.html
  std::string url_path;     // "view/index.html" (relative to OUT)
};

// Writes OUT/view/{index.html, ground.png, cesium -> web/.../Build/Cesium}
// for `city` (empty: the first city with a tileset). `cesium_dir` is
// CesiumJS's Build/Cesium folder. Throws Error when there is no tileset
// (run with --3dtiles) or CesiumJS is missing (scripts/setup.sh).
ViewPage WriteViewPage(const std::string& out_dir, const std::string& city, const std::string& cesium_dir);

// The DSM GeoTIFF coloured by height (transparent where empty), warped to
// WGS84, as a PNG: its bounds and a height just below its lowest cell.
struct GroundImage {
  double west_deg = 0, south_deg = 0, east_deg = 0, north_deg = 0;
  double low_height_m = 0;  // above the WGS84 ellipsoid
};
GroundImage WriteGroundPng(const std::string& dsm_tif, const std::string& png);

}  // namespace skyfall
