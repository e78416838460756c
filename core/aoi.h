// The AOI catalog: what ingestion learns about one area of interest and what
// every later stage reads (serialized as DIR/<AOI>/aoi.json by catalogs/).
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/rpc.h"

namespace skyfall {

// WGS84 geodetic position; height above the ellipsoid (the RPC height datum).
struct GeodeticPoint {
  double lon_deg = 0.0;
  double lat_deg = 0.0;
  double height_m = 0.0;
};

// How an image's raw values become the RGB in [0, 1] that every stage uses
// (features, dense matching, training, PLY colours, renders): one
// normalization per image, measured once at ingestion.
struct Radiometry {
  std::array<int, 3> bands{1, 2, 3};  // source band (1-based) of red, green, blue; a grey image repeats one
  double low = 0.0;                   // raw value mapped to 0
  double high = 255.0;                // raw value mapped to 1
  // "percentile" (robust low/high percentiles of the image) or "type_range"
  // (Byte imagery, display-scaled already); empty: not measured yet.
  std::string method;
  bool has_nodata = false;            // pixels equal to `nodata` are masked
  double nodata = 0.0;
  bool Measured() const { return !method.empty(); }
};

struct ImageRecord {
  std::string name;              // file stem, e.g. "JAX_068_001_RGB"
  std::string path;              // absolute path of the raster
  int width_px = 0;
  int height_px = 0;
  int bands = 0;
  std::string dtype;             // GDAL data type name, e.g. "Byte"
  Radiometry radiometry;
  RpcModel rpc;                  // for this raster's pixel grid (crop offsets applied)
  std::string rpc_source;        // "gdal_metadata", "rpb" or "satnerf_json"
  std::string acquisition_time;  // ISO 8601 UTC ("2014-10-05T16:01:38Z"); empty if unknown
  std::optional<double> sun_elevation_deg;  // when the source states it
  std::optional<double> sun_azimuth_deg;    // clockwise from north
  // Viewing geometry at the image centre, derived from the RPC: the ray from
  // the ground towards the satellite.
  double view_zenith_deg = 0.0;   // incidence angle at the ground
  double view_azimuth_deg = 0.0;  // azimuth of the satellite seen from the ground, from north
  double off_nadir_deg = 0.0;     // angle at the satellite (spherical Earth, nominal orbit)
  std::vector<Eigen::Vector2d> footprint_lonlat;  // image corners at the AOI mid height
};

// The LiDAR truth DSM grid of DFC2019 (_DSM.txt + _DSM.tif + _CLS.tif).
struct TruthGrid {
  std::string dsm_path;
  std::string dsm_txt_path;
  std::string cls_path;              // empty when there is no CLS raster
  std::string ortho_path;            // true orthophoto on the DSM's grid (the synthetic city's); empty: none
  int epsg = 0;                      // UTM EPSG code, e.g. 32617
  double lower_left_easting_m = 0;   // from _DSM.txt, lower-left corner convention
  double lower_left_northing_m = 0;
  int width_px = 0;
  int height_px = 0;
  double gsd_m = 0.0;
  double min_height_m = 0.0;         // finite range of the DSM values
  double max_height_m = 0.0;
  // Upper-left corner: the GeoTIFF origin of this grid.
  double UpperLeftNorthing() const { return lower_left_northing_m + height_px * gsd_m; }
};

struct AoiCatalog {
  std::string aoi;          // "JAX_068"
  std::string source_root;  // the DFC2019 root it was ingested from
  GeodeticPoint enu_origin; // origin of the AOI's local ENU frame
  int utm_zone = 0;
  bool utm_north = true;
  int epsg = 0;
  std::vector<Eigen::Vector2d> footprint_lonlat;  // polygon, counter-clockwise, not closed
  std::string footprint_source;                   // "truth_grid" or "image_overlap"
  double min_ellipsoid_height_m = 0.0;                      // scene height range (ellipsoidal)
  double max_ellipsoid_height_m = 0.0;
  std::string height_range_source;                // "satnerf_json", "truth_dsm" or "rpc"
  std::vector<ImageRecord> images;
  std::optional<TruthGrid> truth;
  std::vector<std::string> train_images;  // Sat-NeRF split (image names) when present
  std::vector<std::string> test_images;
  // A tile of a city whose tiles hold different acquisitions: the
  // acquisitions (acquisition_time) every tile holds. Bundle adjustment fixes
  // the tile's frame by their RPCs' average alone, so that every tile of the
  // city lands in the same frame. Empty: the average of all its images.
  std::vector<std::string> gauge_acquisitions;
};

}  // namespace skyfall
