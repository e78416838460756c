#include "pipeline/tile_report.h"

#include <filesystem>
#include <limits>

#include "core/atomic_file.h"

namespace skyfall {
namespace {

using json = nlohmann::json;

// Figures as written: a NaN went out as null and comes back as NaN.
std::map<std::string, double> MetricsFromJson(const json& j) {
  std::map<std::string, double> metrics;
  for (const auto& [key, value] : j.items())
    metrics[key] = value.is_number() ? value.get<double>() : std::numeric_limits<double>::quiet_NaN();
  return metrics;
}

double SecondsFromJson(const json& j) {
  return j.is_number() ? j.get<double>() : std::numeric_limits<double>::quiet_NaN();
}

StageReport StageReportFromJson(const json& j) {
  StageReport r;
  r.stage = j.at("stage").get<std::string>();
  const std::optional<StageStatus> status = StageStatusFromString(j.at("status").get<std::string>());
  if (!status) throw std::runtime_error("unknown stage status");
  r.status = *status;
  r.message = j.at("message").get<std::string>();
  r.seconds = SecondsFromJson(j.at("seconds"));
  r.metrics = MetricsFromJson(j.at("metrics"));
  r.warnings = j.at("warnings").get<std::vector<std::string>>();
  return r;
}

}  // namespace

double TileReport::PeakRssMb() const {
  const auto it = metrics.find("peak_rss_mb");
  return it == metrics.end() ? 0.0 : it->second;
}

std::string TileReportPath(const std::string& tile_dir) {
  return (std::filesystem::path(tile_dir) / "tile_report.json").string();
}

std::optional<StageStatus> StageStatusFromString(const std::string& text) {
  for (StageStatus s : {StageStatus::kOk, StageStatus::kSkipped, StageStatus::kDegenerate, StageStatus::kFailed})
    if (text == ToString(s)) return s;
  return std::nullopt;
}

json StageReportsJson(const std::vector<StageReport>& reports) {
  json list = json::array();
  for (const StageReport& r : reports)
    list.push_back({{"stage", r.stage}, {"status", ToString(r.status)}, {"message", r.message}, {"seconds", r.seconds},
                    {"metrics", r.metrics}, {"warnings", r.warnings}});
  return list;
}

void WriteTileReport(const std::string& tile_dir, const TileReport& r) {
  const json doc = {{"tile", r.tile}, {"status", ToString(r.status)}, {"message", r.message},
                    {"options", r.options}, {"decisions", r.decisions}, {"images", r.images},
                    {"seconds", r.seconds}, {"metrics", r.metrics}, {"stages", StageReportsJson(r.stages)}};
  WriteFileAtomic(TileReportPath(tile_dir), doc.dump(2) + "\n");
}

std::optional<TileReport> ReadTileReport(const std::string& tile_dir) {
  const std::string path = TileReportPath(tile_dir);
  if (!std::filesystem::exists(path)) return std::nullopt;
  try {
    const json doc = json::parse(ReadTextFile(path));
    TileReport r;
    r.tile = doc.at("tile").get<std::string>();
    const std::optional<StageStatus> status = StageStatusFromString(doc.at("status").get<std::string>());
    if (!status) return std::nullopt;
    r.status = *status;
    r.message = doc.at("message").get<std::string>();
    r.options = doc.at("options");
    r.decisions = doc.value("decisions", json::object());
    r.images = doc.at("images").get<std::size_t>();
    r.seconds = SecondsFromJson(doc.at("seconds"));
    r.metrics = MetricsFromJson(doc.at("metrics"));
    for (const json& s : doc.at("stages")) r.stages.push_back(StageReportFromJson(s));
    return r;
  } catch (const std::exception&) {
    return std::nullopt;  // unreadable: the tile has not finished
  }
}

json ReadRecordOrNull(const std::string& path) {
  try {
    return std::filesystem::exists(path) ? json::parse(ReadTextFile(path)) : json();
  } catch (const std::exception&) {
    return json();
  }
}

}  // namespace skyfall
