#include "catalogs/aoi_catalog.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "catalogs/json_doc.h"
#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall {
namespace {

using json = nlohmann::json;

json LonLatList(const std::vector<Eigen::Vector2d>& points) {
  json out = json::array();
  for (const auto& p : points) out.push_back({p.x(), p.y()});
  return out;
}

std::vector<Eigen::Vector2d> LonLatListFrom(const json& j) {
  std::vector<Eigen::Vector2d> out;
  for (const auto& p : j) out.emplace_back(p.at(0).get<double>(), p.at(1).get<double>());
  return out;
}

json OptionalNumber(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }

std::optional<double> OptionalNumberFrom(const json& obj, const char* key) {
  if (!obj.contains(key) || obj.at(key).is_null()) return std::nullopt;
  return obj.at(key).get<double>();
}

// RPC as the GDAL metadata keys, numbers as numbers (nlohmann writes doubles
// with round-trip precision).
json RpcToJson(const RpcModel& rpc) {
  auto list = [](const std::array<double, 20>& c) { return json(std::vector<double>(c.begin(), c.end())); };
  return {{"LINE_OFF", rpc.line_off},         {"SAMP_OFF", rpc.samp_off},
          {"LAT_OFF", rpc.lat_off},           {"LONG_OFF", rpc.lon_off},
          {"HEIGHT_OFF", rpc.height_off},     {"LINE_SCALE", rpc.line_scale},
          {"SAMP_SCALE", rpc.samp_scale},     {"LAT_SCALE", rpc.lat_scale},
          {"LONG_SCALE", rpc.lon_scale},      {"HEIGHT_SCALE", rpc.height_scale},
          {"LINE_NUM_COEFF", list(rpc.line_num)}, {"LINE_DEN_COEFF", list(rpc.line_den)},
          {"SAMP_NUM_COEFF", list(rpc.samp_num)}, {"SAMP_DEN_COEFF", list(rpc.samp_den)},
          {"ERR_BIAS", rpc.err_bias_m},       {"ERR_RAND", rpc.err_rand_m}};
}

RpcModel RpcFromJson(const json& j) {
  RpcModel rpc;
  auto list = [&](const char* key) {
    const auto v = j.at(key).get<std::vector<double>>();
    if (v.size() != 20) throw Error("catalog", key, "must hold 20 coefficients");
    std::array<double, 20> out{};
    std::copy(v.begin(), v.end(), out.begin());
    return out;
  };
  rpc.line_off = j.at("LINE_OFF").get<double>();
  rpc.samp_off = j.at("SAMP_OFF").get<double>();
  rpc.lat_off = j.at("LAT_OFF").get<double>();
  rpc.lon_off = j.at("LONG_OFF").get<double>();
  rpc.height_off = j.at("HEIGHT_OFF").get<double>();
  rpc.line_scale = j.at("LINE_SCALE").get<double>();
  rpc.samp_scale = j.at("SAMP_SCALE").get<double>();
  rpc.lat_scale = j.at("LAT_SCALE").get<double>();
  rpc.lon_scale = j.at("LONG_SCALE").get<double>();
  rpc.height_scale = j.at("HEIGHT_SCALE").get<double>();
  rpc.line_num = list("LINE_NUM_COEFF");
  rpc.line_den = list("LINE_DEN_COEFF");
  rpc.samp_num = list("SAMP_NUM_COEFF");
  rpc.samp_den = list("SAMP_DEN_COEFF");
  rpc.err_bias_m = j.value("ERR_BIAS", -1.0);
  rpc.err_rand_m = j.value("ERR_RAND", -1.0);
  rpc.Validate();
  return rpc;
}

json RadiometryToJson(const Radiometry& r) {
  return {{"bands", r.bands}, {"low", r.low}, {"high", r.high}, {"method", r.method},
          {"nodata", r.has_nodata ? json(r.nodata) : json(nullptr)}};
}

}  // namespace

std::string RadiometryJson(const Radiometry& r) { return RadiometryToJson(r).dump(); }

Radiometry RadiometryFromJson(const std::string& text, const std::string& subject) {
  Radiometry r;
  try {
    const json j = json::parse(text);
    std::vector<int> bands;
    for (const json& b : j.at("bands")) bands.push_back(catalogs::JsonInt(b, subject, "bands[]"));
    if (bands.size() != 3) throw Error("catalog", subject + ".bands", "must list 3 bands (red, green, blue)");
    for (int k = 0; k < 3; ++k) {
      if (bands[k] < 1) throw Error("catalog", subject + ".bands", "band numbers start at 1, got " + std::to_string(bands[k]));
      r.bands[k] = bands[k];
    }
    r.low = j.at("low").get<double>();
    r.high = j.at("high").get<double>();
    r.method = j.at("method").get<std::string>();
    r.has_nodata = j.contains("nodata") && !j.at("nodata").is_null();
    if (r.has_nodata) r.nodata = j.at("nodata").get<double>();
  } catch (const json::exception& e) {
    throw Error("catalog", subject, std::string("bad radiometry: ") + e.what());
  }
  if (!(std::isfinite(r.low) && std::isfinite(r.high) && r.high > r.low))
    throw Error("catalog", subject, "radiometry needs finite low < high, got " + std::to_string(r.low) + " and " +
                                        std::to_string(r.high));
  return r;
}

namespace {

json ImageToJson(const ImageRecord& im) {
  return {{"name", im.name},
          {"path", im.path},
          {"width_px", im.width_px},
          {"height_px", im.height_px},
          {"bands", im.bands},
          {"dtype", im.dtype},
          {"radiometry", im.radiometry.Measured() ? RadiometryToJson(im.radiometry) : json(nullptr)},
          {"acquisition_time", im.acquisition_time},
          {"sun_elevation_deg", OptionalNumber(im.sun_elevation_deg)},
          {"sun_azimuth_deg", OptionalNumber(im.sun_azimuth_deg)},
          {"view_zenith_deg", im.view_zenith_deg},
          {"view_azimuth_deg", im.view_azimuth_deg},
          {"off_nadir_deg", im.off_nadir_deg},
          {"footprint_lonlat", LonLatList(im.footprint_lonlat)},
          {"rpc_source", im.rpc_source},
          {"rpc", RpcToJson(im.rpc)}};
}

ImageRecord ImageFromJson(const json& j) {
  ImageRecord im;
  im.name = j.at("name").get<std::string>();
  im.path = j.at("path").get<std::string>();
  im.width_px = catalogs::JsonInt(j.at("width_px"), "images[]", "width_px");
  im.height_px = catalogs::JsonInt(j.at("height_px"), "images[]", "height_px");
  im.bands = catalogs::JsonInt(j.at("bands"), "images[]", "bands");
  im.dtype = j.at("dtype").get<std::string>();
  // Catalogs written before radiometry was recorded: measured when read.
  if (j.contains("radiometry") && !j.at("radiometry").is_null())
    im.radiometry = RadiometryFromJson(j.at("radiometry").dump(), "images[" + im.name + "].radiometry");
  im.acquisition_time = j.value("acquisition_time", std::string());
  im.sun_elevation_deg = OptionalNumberFrom(j, "sun_elevation_deg");
  im.sun_azimuth_deg = OptionalNumberFrom(j, "sun_azimuth_deg");
  im.view_zenith_deg = j.at("view_zenith_deg").get<double>();
  im.view_azimuth_deg = j.at("view_azimuth_deg").get<double>();
  im.off_nadir_deg = j.at("off_nadir_deg").get<double>();
  im.footprint_lonlat = LonLatListFrom(j.at("footprint_lonlat"));
  im.rpc_source = j.value("rpc_source", std::string());
  try {
    im.rpc = RpcFromJson(j.at("rpc"));
  } catch (const Error& e) {
    throw Error("catalog", "images[" + im.name + "].rpc." + e.subject(), e.detail());
  }
  return im;
}

json TruthToJson(const TruthGrid& t) {
  json j = {{"dsm_path", t.dsm_path},
          {"dsm_txt_path", t.dsm_txt_path},
          {"cls_path", t.cls_path.empty() ? json(nullptr) : json(t.cls_path)},
          {"epsg", t.epsg},
          {"lower_left_easting_m", t.lower_left_easting_m},
          {"lower_left_northing_m", t.lower_left_northing_m},
          {"upper_left_northing_m", t.UpperLeftNorthing()},
          {"width_px", t.width_px},
          {"height_px", t.height_px},
          {"gsd_m", t.gsd_m},
          {"min_height_m", t.min_height_m},
          {"max_height_m", t.max_height_m}};
  if (!t.ortho_path.empty()) j["ortho_path"] = t.ortho_path;
  return j;
}

TruthGrid TruthFromJson(const json& j) {
  TruthGrid t;
  t.dsm_path = j.at("dsm_path").get<std::string>();
  t.dsm_txt_path = j.at("dsm_txt_path").get<std::string>();
  t.cls_path = j.at("cls_path").is_null() ? "" : j.at("cls_path").get<std::string>();
  t.ortho_path = j.value("ortho_path", std::string());
  t.epsg = catalogs::JsonInt(j.at("epsg"), "truth", "epsg");
  t.lower_left_easting_m = j.at("lower_left_easting_m").get<double>();
  t.lower_left_northing_m = j.at("lower_left_northing_m").get<double>();
  t.width_px = catalogs::JsonInt(j.at("width_px"), "truth", "width_px");
  t.height_px = catalogs::JsonInt(j.at("height_px"), "truth", "height_px");
  t.gsd_m = j.at("gsd_m").get<double>();
  t.min_height_m = j.at("min_height_m").get<double>();
  t.max_height_m = j.at("max_height_m").get<double>();
  return t;
}

}  // namespace

std::string AoiCatalogToJson(const AoiCatalog& c) {
  json images = json::array();
  for (const auto& im : c.images) images.push_back(ImageToJson(im));
  json doc = {
      {"schema", kAoiCatalogSchema},
      {"aoi", c.aoi},
      {"source_root", c.source_root},
      {"enu_origin", {{"lon_deg", c.enu_origin.lon_deg}, {"lat_deg", c.enu_origin.lat_deg},
                      {"height_m", c.enu_origin.height_m}}},
      {"utm", {{"zone", c.utm_zone}, {"north", c.utm_north}, {"epsg", c.epsg}}},
      {"footprint_lonlat", LonLatList(c.footprint_lonlat)},
      {"footprint_source", c.footprint_source},
      {"height_range_m", {c.min_ellipsoid_height_m, c.max_ellipsoid_height_m}},
      {"height_range_source", c.height_range_source},
      {"truth", c.truth ? TruthToJson(*c.truth) : json(nullptr)},
      {"split", {{"train", c.train_images}, {"test", c.test_images}}},
      {"images", images},
  };
  if (!c.gauge_acquisitions.empty()) doc["gauge_acquisitions"] = c.gauge_acquisitions;
  return doc.dump(2) + "\n";
}

AoiCatalog AoiCatalogFromJson(const std::string& text, const std::string& subject) {
  const json doc = catalogs::ParseVersioned(text, subject, kAoiCatalogSchema);
  AoiCatalog c;
  try {
    c.aoi = doc.at("aoi").get<std::string>();
    c.source_root = doc.value("source_root", std::string());
    const json& o = doc.at("enu_origin");
    c.enu_origin = {o.at("lon_deg").get<double>(), o.at("lat_deg").get<double>(),
                    o.at("height_m").get<double>()};
    c.utm_zone = catalogs::JsonInt(doc.at("utm").at("zone"), subject, "utm.zone");
    c.utm_north = doc.at("utm").at("north").get<bool>();
    c.epsg = catalogs::JsonInt(doc.at("utm").at("epsg"), subject, "utm.epsg");
    c.footprint_lonlat = LonLatListFrom(doc.at("footprint_lonlat"));
    c.footprint_source = doc.value("footprint_source", std::string());
    c.min_ellipsoid_height_m = doc.at("height_range_m").at(0).get<double>();
    c.max_ellipsoid_height_m = doc.at("height_range_m").at(1).get<double>();
    c.height_range_source = doc.value("height_range_source", std::string());
    if (!doc.at("truth").is_null()) c.truth = TruthFromJson(doc.at("truth"));
    if (doc.contains("split")) {
      c.train_images = doc.at("split").value("train", std::vector<std::string>{});
      c.test_images = doc.at("split").value("test", std::vector<std::string>{});
    }
    for (const json& im : doc.at("images")) c.images.push_back(ImageFromJson(im));
    c.gauge_acquisitions = doc.value("gauge_acquisitions", std::vector<std::string>{});
  } catch (const json::exception& e) {
    throw Error("catalog", subject, std::string("bad or missing field: ") + e.what());
  } catch (const Error& e) {
    throw e.Within(subject);
  }
  return c;
}

void WriteAoiCatalog(const std::string& path, const AoiCatalog& catalog) {
  WriteFileAtomic(path, AoiCatalogToJson(catalog));
}

AoiCatalog ReadAoiCatalog(const std::string& path) {
  return AoiCatalogFromJson(ReadTextFile(path), path);
}

}  // namespace skyfall
