// Reading RPC cameras from the formats users have: GDAL RPC metadata (GeoTIFF
// RPC tags, NITF RPC00B, and the sidecars GDAL attaches to an image:
// <image>_RPC.TXT, <image>.RPB, DigitalGlobe <image>.XML, DIMAP RPC_*.XML),
// and files given directly: .RPB text, "KEY: value" RPC text, Sat-NeRF camera
// JSONs and the vendor XMLs of ingest/vendor_rpc.h. Every reader validates the
// model and names the file and the field on error.
//
// Pixel convention (core/rpc.h): first pixel centre at (0, 0). GDAL's RPC
// metadata is in that convention already (its DIMAP reader subtracts DIMAP's
// 1-based origin itself); GDAL's transformer adds the half pixel of its
// corner-based pixel/line (ingest/gdal_rpc_check.h).
#pragma once

#include <map>
#include <optional>
#include <string>

#include "core/rpc.h"

namespace skyfall {

// GDAL "RPC" metadata domain -> model, read by GDAL itself
// (GDALExtractRPCInfoV2: the values every GDAL tool uses; unit words after a
// number are ignored, as IKONOS _rpc.txt sidecars need). Our own stricter
// reading of the same text comes first so that a missing key or a value that
// is no number is named, where GDAL would quietly read it as 0.
RpcModel RpcFromGdalRpcDomain(const std::map<std::string, std::string>& rpc_metadata);

// From the raster's GDAL "RPC" metadata domain (its tags or GDAL's sidecars).
RpcModel ReadRpcFromRaster(const std::string& raster_path);

// From a DigitalGlobe .RPB text file.
RpcModel ReadRpbFile(const std::string& rpb_path);

// From a "KEY: value" RPC text file (_RPC.TXT, _rpc.txt).
RpcModel ReadRpcTextFile(const std::string& path);

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

struct RpcReadOptions {
  // Files holding one model per band (EnMAP metadata): the band number, from
  // 1. 0: the default band (kEnmapDefaultBand). Refused for other files.
  int band = 0;
};

// Picks the reader by the file's content, whatever its name
// (DetectRpcFileFormat): Sat-NeRF JSON, .RPB text, KEY: value text, DIMAP /
// DigitalGlobe / EnMAP XML, else a raster or VRT GDAL opens. `source`
// (optional) receives RpcFileFormatName of the format read. A file holding no
// RPC is refused with an Error naming it.
RpcModel ReadRpcAny(const std::string& path, std::string* source = nullptr,
                    const RpcReadOptions& options = {});

// "20141005160138" (NITF IDATIM, YYYYMMDDhhmmss) -> "2014-10-05T16:01:38Z".
// Returns an empty string when the text is not such a date.
std::string IsoTimeFromCompact(const std::string& yyyymmddhhmmss);

}  // namespace skyfall
