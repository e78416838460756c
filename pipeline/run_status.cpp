#include "pipeline/run_status.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>

#include "core/atomic_file.h"
#include "core/error.h"
#include "products/city_report.h"
#include "pipeline/slurm.h"
#include "pipeline/tile_report.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::string TileState(const fs::path& tile_dir) {
  if (fs::exists(TileReportPath(tile_dir.string()))) {
    const std::optional<TileReport> report = ReadTileReport(tile_dir.string());
    return report ? ToString(report->status) : "failed";  // an unreadable report
  }
  return fs::exists(tile_dir / "run.log") ? "started" : "waiting";
}

json CityStatus(const fs::path& city_dir, bool ask_scheduler) {
  json tiles = json::array();
  const json index = json::parse(ReadTextFile((city_dir / "tiles" / "tiles.json").string()));
  SlurmCityJobs jobs;
  const bool slurm = ReadSlurmJobs(city_dir.string(), &jobs);
  std::map<int, std::string> tasks;
  std::string finish_state;
  if (slurm && ask_scheduler) {
    if (!jobs.tiles_job.empty()) tasks = SlurmArrayTaskStates(jobs.tiles_job);
    finish_state = SlurmJobState(jobs.finish_job);
  }
  int done = 0;
  for (const json& t : index.at("tiles")) {
    const std::string id = t.at("id");
    const fs::path dir = city_dir / "tiles" / id;
    const std::string state = TileState(dir);
    done += state == "ok" || state == "degenerate" || state == "skipped";
    std::string scheduler;
    const auto it = std::find_if(jobs.tiles.begin(), jobs.tiles.end(),
                                 [&](const std::string& p) { return fs::path(p).filename() == id; });
    if (it != jobs.tiles.end()) {
      const auto task = tasks.find(static_cast<int>(it - jobs.tiles.begin()));
      if (task != tasks.end()) scheduler = task->second;
    }
    tiles.push_back({{"tile", id}, {"state", state}, {"scheduler", scheduler}});
  }
  std::string city_state = "incomplete";
  if (fs::exists(CityReportPath(city_dir))) {
    const std::optional<CityReport> report = ReadCityReport(CityReportPath(city_dir).string());
    city_state = report && report->scene ? "done" : "failed";
  }
  if (!finish_state.empty()) city_state = "running";
  json slurm_json = nullptr;
  if (slurm) {
    slurm_json = {{"tiles_job", jobs.tiles_job}, {"finish_job", jobs.finish_job}, {"finish_state", finish_state},
                  {"submitted_utc", jobs.submitted_utc}};
  }
  return {{"city", city_dir.filename().string()},
          {"state", city_state},
          {"tiles_done", done},
          {"tiles_total", tiles.size()},
          {"slurm", slurm_json},
          {"tiles", tiles}};
}

}  // namespace

json RunStatus(const std::string& out_dir, bool ask_scheduler) {
  if (!fs::is_directory(out_dir)) throw Error("status", out_dir, "is not a folder");
  std::vector<fs::path> cities;
  for (const auto& entry : fs::directory_iterator(out_dir)) {
    if (fs::exists(entry.path() / "tiles" / "tiles.json")) cities.push_back(entry.path());
  }
  if (cities.empty()) throw Error("status", out_dir, "holds no run (no <city>/tiles/tiles.json)");
  std::sort(cities.begin(), cities.end());
  json list = json::array();
  for (const fs::path& c : cities) list.push_back(CityStatus(c, ask_scheduler));
  return {{"out", out_dir}, {"cities", list}};
}

std::string RunStatusText(const json& status) {
  std::string text;
  for (const json& c : status.at("cities")) {
    text += fmt::format("{}: {} ({}/{} tiles finished)", c.at("city").get<std::string>(),
                        c.at("state").get<std::string>(), c.at("tiles_done").get<int>(), c.at("tiles_total").get<int>());
    if (!c.at("slurm").is_null()) {
      const json& s = c.at("slurm");
      const std::string finish = s.at("finish_state");
      text += fmt::format("; Slurm tiles job {}, finish job {} ({})", s.at("tiles_job").get<std::string>(),
                          s.at("finish_job").get<std::string>(), finish.empty() ? "not queued" : finish);
    }
    text += "\n";
    for (const json& t : c.at("tiles")) {
      const std::string scheduler = t.at("scheduler");
      text += fmt::format("  {:<28} {}{}\n", t.at("tile").get<std::string>(), t.at("state").get<std::string>(),
                          scheduler.empty() ? "" : " (Slurm: " + scheduler + ")");
    }
  }
  return text;
}

}  // namespace skyfall
