#include "products/city_report.h"

#include "core/atomic_file.h"

namespace skyfall {
namespace {

using json = nlohmann::json;

std::optional<double> NumberOrNullopt(const json& j) {
  if (!j.is_number()) return std::nullopt;
  return j.get<double>();
}

// A list of objects whose `key`, where present, is a string.
bool ArrayOfObjects(const json& list, const char* key) {
  if (!list.is_array()) return false;
  for (const json& entry : list)
    if (!entry.is_object() || (entry.contains(key) && !entry.at(key).is_string())) return false;
  return true;
}

}  // namespace

bool CityReport::AnyTileFailed() const {
  for (const json& tile : tiles)
    if (tile.value("status", "failed") == "failed") return true;
  return false;
}

std::optional<double> CityReport::DsmMaeM(const std::string& aoi) const {
  for (const json& entry : dsm)
    if (entry.value("aoi", "") == aoi) return NumberOrNullopt(entry.value("mae_m", json()));
  return std::nullopt;
}

std::optional<std::vector<double>> CityReport::DsmMaesM() const {
  std::vector<double> mae;
  for (const json& entry : dsm) {
    const std::optional<double> m = NumberOrNullopt(entry.value("mae_m", json()));
    if (!m) return std::nullopt;
    mae.push_back(*m);
  }
  return mae;
}

std::filesystem::path CityReportPath(const std::filesystem::path& city_dir) { return city_dir / "run_report.json"; }

void WriteCityReport(const std::string& path, const CityReport& r) {
  json doc = {{"city", r.city}, {"options", r.options}, {"tiles", r.tiles},
              {"aois", r.aois}, {"stages", r.stages},   {"seconds", r.seconds}};
  if (r.scene) {
    doc["scene"] = *r.scene;
    doc["dsm"] = r.dsm;
    doc["products"] = r.products;
    doc["city_products"] = r.city_products;
    if (r.tiles3d) doc["tiles3d"] = *r.tiles3d;
    doc["merge"] = r.merge;
    doc["decisions"] = r.decisions;
    doc["seam"] = r.seam;
    doc["peak_tile_rss_mb"] = r.peak_tile_rss_mb;
    doc["inputs"] = r.inputs;
  }
  WriteFileAtomic(path, doc.dump(2) + "\n");
}

std::optional<CityReport> ReadCityReport(const std::string& path, std::string* why) {
  auto fail = [&](const std::string& reason) -> std::optional<CityReport> {
    if (why) *why = reason;
    return std::nullopt;
  };
  std::error_code unreadable;
  if (!std::filesystem::exists(path, unreadable)) return fail("there is no run report");
  try {
    const json doc = json::parse(ReadTextFile(path));
    CityReport r;
    r.city = doc.at("city").get<std::string>();
    r.options = doc.value("options", json());
    r.tiles = doc.at("tiles");
    if (!ArrayOfObjects(r.tiles, "status")) return fail("\"tiles\" is not a list of tile entries");
    r.aois = doc.value("aois", std::vector<std::string>());
    r.stages = doc.value("stages", json::array());
    r.seconds = NumberOrNullopt(doc.value("seconds", json())).value_or(CityReport::kUnknown);
    if (doc.contains("scene")) {
      r.scene = doc.at("scene").get<std::string>();
      r.dsm = doc.value("dsm", json::array());
      if (!ArrayOfObjects(r.dsm, "aoi")) return fail("\"dsm\" is not a list of comparisons");
      r.products = doc.value("products", json::array());
      r.city_products = doc.value("city_products", json());
      if (doc.contains("tiles3d")) r.tiles3d = doc.at("tiles3d");
      r.merge = doc.value("merge", json());
      r.decisions = doc.value("decisions", json());
      r.seam = doc.value("seam", json());
      r.peak_tile_rss_mb = NumberOrNullopt(doc.value("peak_tile_rss_mb", json())).value_or(CityReport::kUnknown);
      r.inputs = doc.value("inputs", json());
    }
    return r;
  } catch (const std::exception& e) {
    return fail(e.what());  // not JSON, or a field of the wrong kind
  }
}

}  // namespace skyfall
