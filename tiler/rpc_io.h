// Reading RPC cameras from the formats users have: GDAL RPC metadata (GeoTIFF
// RPC tags, NITF RPC00B, _RPC.TXT/.RPB sidecars as GDAL reports them),
// DigitalGlobe .RPB text files and Sat-NeRF camera JSONs. Every reader
// validates the model and names the file and the field on error.
#pragma once

#include <optional>
#include <string>

#include "core/rpc.h"

namespace skyfall {

// From the raster's GDAL "RPC" metadata domain.
RpcModel ReadRpcFromRaster(const std::string& raster_path);

// From a DigitalGlobe .RPB text file.
RpcModel ReadRpbFile(const std::string& rpb_path);

// What a Sat-NeRF camera JSON holds besides the RPC.
struct SatNerfCamera {
  std::string image;                      // "img": raster file name
  int width_px = 0;
  int height_px = 0;
  RpcModel rpc;
  std::optional<double> sun_elevation_deg;
  std::optional<double> sun_azimuth_deg;
  std::string acquisition_time;           // ISO 8601 UTC; empty if absent
  std::optional<double> min_alt_m;        // scene height range hints
  std::optional<double> max_alt_m;
};

// Parses Sat-NeRF JSON text; `subject` names the source in errors.
SatNerfCamera ParseSatNerfCamera(const std::string& json_text, const std::string& subject);
SatNerfCamera ReadSatNerfCamera(const std::string& json_path);

// Picks the reader by file name: *.json -> Sat-NeRF, *.rpb -> RPB, anything
// else -> raster metadata. `source` (optional) receives "satnerf_json", "rpb"
// or "gdal_metadata".
RpcModel ReadRpcAny(const std::string& path, std::string* source = nullptr);

// "20141005160138" (NITF IDATIM, YYYYMMDDhhmmss) -> "2014-10-05T16:01:38Z".
// Returns an empty string when the text is not such a date.
std::string IsoTimeFromCompact(const std::string& yyyymmddhhmmss);

}  // namespace skyfall
