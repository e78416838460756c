// A static STAC 1.1 catalog beside a run's products, so that a GIS or a data
// platform can find and read them without knowing the folder layout:
//   OUT/catalog.json                      Catalog: one child per city
//   OUT/<city>/collection.json            Collection: extent from the inputs
//   OUT/<AOI>/<AOI>.json                  Item: the AOI's DSM, error maps,
//                                         reports, the city's scene and LOD
//   OUT/<city>/tiles/<id>/<id>.json       Item: a tile's scene and reports
// Every link is relative, so the folder can be moved or served as it is.
// Assets carry file:size and file:checksum (SHA-256 multihash); GeoTIFFs
// carry proj:code/shape/transform read back from the file and their band's
// nodata, data type, unit and statistics.
#pragma once

#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/format.h"  // UtcNowIso

namespace skyfall {

inline constexpr const char* kStacVersion = "1.1.0";
inline constexpr const char* kStacProjection = "https://stac-extensions.github.io/projection/v2.0.0/schema.json";
inline constexpr const char* kStacRaster = "https://stac-extensions.github.io/raster/v2.0.0/schema.json";
inline constexpr const char* kStacFile = "https://stac-extensions.github.io/file/v2.1.0/schema.json";

// What the catalog of one city describes (paths as the run wrote them).
struct StacCity {
  std::string city;
  std::string out_dir;                  // OUT
  std::vector<AoiCatalog> aois;
  std::vector<std::string> tile_dirs;   // tiles with a tile_report.json get an Item
  std::string scene_dir;                // OUT/<city>/scene
  std::string run_report;               // OUT/<city>/run_report.json
  std::string processed_utc;            // datetime when no acquisition time is known
};

// Writes the city's Collection and Items (each only when its content changed).
// Returns the Collection's path.
std::string WriteCityStac(const StacCity& city);

// Writes OUT/catalog.json with one child per OUT/*/collection.json.
std::string WriteRootStacCatalog(const std::string& out_dir);

}  // namespace skyfall
