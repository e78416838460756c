#include "ingest/rpc_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>

#include <cpl_string.h>
#include <gdal.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "ingest/gdal_util.h"
#include "ingest/raster.h"
#include "ingest/vendor_rpc.h"

namespace skyfall {
namespace {

using json = nlohmann::json;

// Sat-NeRF stores numbers either as JSON numbers or as strings ("+50.8").
double NumberField(const json& obj, const std::string& key, const std::string& subject) {
  if (!obj.contains(key)) throw Error("rpc", subject, "field '" + key + "' is missing");
  const json& v = obj.at(key);
  if (v.is_number()) return v.get<double>();
  if (v.is_string()) {
    const std::string s = v.get<std::string>();
    char* end = nullptr;
    const double d = std::strtod(s.c_str(), &end);
    if (end != s.c_str() && *end == '\0') return d;
  }
  if (v.is_null()) return std::nan("");  // json has no NaN; writers emit null for it
  throw Error("rpc", subject, "field '" + key + "' is not a number: " + v.dump());
}

std::optional<double> OptionalNumber(const json& obj, const std::string& key,
                                     const std::string& subject) {
  if (!obj.contains(key)) return std::nullopt;
  const double v = NumberField(obj, key, subject);
  if (!std::isfinite(v)) return std::nullopt;
  return v;
}

std::string CoeffList(const json& rpc, const std::string& key, const std::string& subject) {
  if (!rpc.contains(key) || !rpc.at(key).is_array()) {
    throw Error("rpc", subject, "field 'rpc." + key + "' is missing or not a list");
  }
  std::string out;
  for (const json& c : rpc.at(key)) {
    if (c.is_null()) {
      out += " nan";
    } else if (c.is_number()) {
      char buf[40];
      std::snprintf(buf, sizeof(buf), " %.17g", c.get<double>());
      out += buf;
    } else {
      throw Error("rpc", subject, "field 'rpc." + key + "' holds a non-number: " + c.dump());
    }
  }
  return out;
}

}  // namespace

RpcModel RpcFromGdalRpcDomain(const std::map<std::string, std::string>& rpc_metadata) {
  // Our reading names a missing key or a malformed value; GDAL's would read
  // those as 0 (and a coefficient list it splits otherwise leaves all 20 at
  // 0), so the two must agree field by field.
  const RpcModel strict = RpcFromGdalMetadata(rpc_metadata);
  CPLStringList list;
  for (const auto& [key, value] : rpc_metadata) list.SetNameValue(key.c_str(), value.c_str());
  GDALRPCInfoV2 info{};
  gdal::QuietErrors quiet;
  if (!GDALExtractRPCInfoV2(list.List(), &info)) {
    throw Error("rpc", "RPC metadata", "GDAL cannot read it: " + quiet.LastMessage());
  }
  RpcModel rpc;
  rpc.line_off = info.dfLINE_OFF;
  rpc.samp_off = info.dfSAMP_OFF;
  rpc.lat_off = info.dfLAT_OFF;
  rpc.lon_off = info.dfLONG_OFF;
  rpc.height_off = info.dfHEIGHT_OFF;
  rpc.line_scale = info.dfLINE_SCALE;
  rpc.samp_scale = info.dfSAMP_SCALE;
  rpc.lat_scale = info.dfLAT_SCALE;
  rpc.lon_scale = info.dfLONG_SCALE;
  rpc.height_scale = info.dfHEIGHT_SCALE;
  for (int i = 0; i < 20; ++i) {
    rpc.line_num[i] = info.adfLINE_NUM_COEFF[i];
    rpc.line_den[i] = info.adfLINE_DEN_COEFF[i];
    rpc.samp_num[i] = info.adfSAMP_NUM_COEFF[i];
    rpc.samp_den[i] = info.adfSAMP_DEN_COEFF[i];
  }
  rpc.err_bias_m = info.dfERR_BIAS;  // GDAL, like us, says -1 when unknown
  rpc.err_rand_m = info.dfERR_RAND;
  const std::map<std::string, std::string> ours = RpcToGdalMetadata(strict), gdals = RpcToGdalMetadata(rpc);
  for (const auto& [key, value] : gdals) {
    if (ours.at(key) != value) {
      throw Error("rpc", key, "GDAL reads '" + value + "' where the text says '" + ours.at(key) + "'");
    }
  }
  rpc.Validate();
  return rpc;
}

RpcModel ReadRpcFromRaster(const std::string& raster_path) {
  const RasterInfo info = ReadRasterInfo(raster_path);
  if (info.rpc_metadata.empty()) {
    throw Error("rpc", raster_path,
                "no RPC metadata (no GeoTIFF RPC tag, NITF RPC00B TRE or sidecar GDAL reads: "
                "_RPC.TXT, .RPB, DigitalGlobe .XML, DIMAP RPC_*.XML)");
  }
  try {
    return RpcFromGdalRpcDomain(info.rpc_metadata);
  } catch (const Error& e) {
    throw e.Within(raster_path);
  }
}

RpcModel ReadRpbFile(const std::string& rpb_path) {
  const std::string text = ReadTextFile(rpb_path);
  try {
    return RpcFromRpbText(text);
  } catch (const Error& e) {
    throw e.Within(rpb_path);
  }
}

RpcModel ReadRpcTextFile(const std::string& path) {
  const std::string text = ReadTextFile(path);
  try {
    return RpcFromKeyValueText(text);
  } catch (const Error& e) {
    throw e.Within(path);
  }
}

SatNerfCamera ParseSatNerfCamera(const std::string& json_text, const std::string& subject) {
  json doc;
  try {
    doc = json::parse(json_text);
  } catch (const json::exception& e) {
    throw Error("rpc", subject, std::string("not valid JSON: ") + e.what());
  }
  if (!doc.is_object() || !doc.contains("rpc") || !doc.at("rpc").is_object()) {
    throw Error("rpc", subject, "no 'rpc' object (not a Sat-NeRF camera JSON)");
  }
  const json& r = doc.at("rpc");
  // Sat-NeRF's names (rpcm convention) -> GDAL keys; the term order is the
  // same RPC00B order.
  static const std::pair<const char*, const char*> kScalars[] = {
      {"row_offset", "LINE_OFF"},   {"col_offset", "SAMP_OFF"},   {"lat_offset", "LAT_OFF"},
      {"lon_offset", "LONG_OFF"},   {"alt_offset", "HEIGHT_OFF"}, {"row_scale", "LINE_SCALE"},
      {"col_scale", "SAMP_SCALE"},  {"lat_scale", "LAT_SCALE"},   {"lon_scale", "LONG_SCALE"},
      {"alt_scale", "HEIGHT_SCALE"}};
  static const std::pair<const char*, const char*> kLists[] = {{"row_num", "LINE_NUM_COEFF"},
                                                               {"row_den", "LINE_DEN_COEFF"},
                                                               {"col_num", "SAMP_NUM_COEFF"},
                                                               {"col_den", "SAMP_DEN_COEFF"}};
  std::map<std::string, std::string> keys;
  const std::string rpc_subject = subject;
  for (const auto& [name, key] : kScalars) {
    char buf[40];
    std::snprintf(buf, sizeof(buf), "%.17g", NumberField(r, name, rpc_subject));
    keys[key] = buf;
  }
  for (const auto& [name, key] : kLists) keys[key] = CoeffList(r, name, rpc_subject);

  SatNerfCamera cam;
  try {
    cam.rpc = RpcFromGdalMetadata(keys);
  } catch (const Error& e) {
    // Translate the GDAL key back to the JSON field the user can find.
    std::string field = e.subject();
    for (const auto& [name, key] : kScalars)
      if (field == key) field = std::string("rpc.") + name;
    for (const auto& [name, key] : kLists)
      if (field.rfind(key, 0) == 0) field = std::string("rpc.") + name + field.substr(std::strlen(key));
    throw Error("rpc", subject + ": " + field, e.detail());
  }
  cam.image = doc.value("img", std::string());
  cam.width_px = doc.value("width", 0);
  cam.height_px = doc.value("height", 0);
  cam.sun_elevation_deg = OptionalNumber(doc, "sun_elevation", subject);
  cam.sun_azimuth_deg = OptionalNumber(doc, "sun_azimuth", subject);
  if (doc.contains("acquisition_date") && doc.at("acquisition_date").is_string()) {
    cam.acquisition_time = IsoTimeFromCompact(doc.at("acquisition_date").get<std::string>());
  }
  cam.min_alt_m = OptionalNumber(doc, "min_alt", subject);
  cam.max_alt_m = OptionalNumber(doc, "max_alt", subject);
  return cam;
}

SatNerfCamera ReadSatNerfCamera(const std::string& json_path) {
  return ParseSatNerfCamera(ReadTextFile(json_path), json_path);
}

namespace {

// A text file that none of our readers takes and GDAL does not open.
Error NoRpcIn(const std::string& path, const Error& gdal_error) {
  return Error("rpc", path,
               "holds no RPC: it is no Sat-NeRF JSON, .RPB, KEY: value RPC text, DIMAP RPC XML, "
               "DigitalGlobe/Maxar XML or EnMAP metadata, and GDAL does not read an RPC from it (" +
                   gdal_error.detail() + ")");
}

}  // namespace

RpcModel ReadRpcAny(const std::string& path, std::string* source, const RpcReadOptions& options) {
  const RpcFileFormat format = DetectRpcFileFormat(path);
  if (options.band != 0 && format != RpcFileFormat::kEnmapXml) {
    throw Error("rpc", path, "holds one RPC model; a band (" + std::to_string(options.band) +
                                 ") can only be chosen in EnMAP metadata");
  }
  RpcModel rpc;
  switch (format) {
    case RpcFileFormat::kSatNerfJson: rpc = ReadSatNerfCamera(path).rpc; break;
    case RpcFileFormat::kRpbText: rpc = ReadRpbFile(path); break;
    case RpcFileFormat::kKeyValueText: rpc = ReadRpcTextFile(path); break;
    case RpcFileFormat::kDimapXml: rpc = ReadDimapRpcXml(path); break;
    case RpcFileFormat::kDigitalGlobeXml: rpc = ReadDigitalGlobeXml(path); break;
    case RpcFileFormat::kEnmapXml:
      rpc = ReadEnmapRpc(path, options.band != 0 ? options.band : kEnmapDefaultBand);
      break;
    case RpcFileFormat::kGdalDataset: rpc = ReadRpcFromRaster(path); break;
    case RpcFileFormat::kUnknownText:
      try {
        rpc = ReadRpcFromRaster(path);
      } catch (const Error& e) {
        throw NoRpcIn(path, e);
      }
      break;
  }
  // Text that GDAL did read (a format it knows and we do not) came through its metadata.
  const bool via_gdal = format == RpcFileFormat::kUnknownText;
  if (source) *source = RpcFileFormatName(via_gdal ? RpcFileFormat::kGdalDataset : format);
  return rpc;
}

std::string IsoTimeFromCompact(const std::string& s) {
  if (s.size() < 14 || !std::all_of(s.begin(), s.begin() + 14, ::isdigit)) return "";
  return s.substr(0, 4) + "-" + s.substr(4, 2) + "-" + s.substr(6, 2) + "T" + s.substr(8, 2) +
         ":" + s.substr(10, 2) + ":" + s.substr(12, 2) + "Z";
}

}  // namespace skyfall
