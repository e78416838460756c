// tile_report.json, what a tile's run writes last: its status, the options it
// ran under, its decisions, times and stages. One writer and one reader; every
// part of the run that looks at a finished tile goes through them.
#pragma once

#include <cstddef>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/stage.h"

namespace skyfall {

struct TileReport {
  std::string tile;  // the tile's id
  StageStatus status = StageStatus::kFailed;
  std::string message;
  nlohmann::json options;                              // TileOptionsJson when it ran (the resume stamp)
  nlohmann::json decisions = nlohmann::json::object();  // what each stage decided and why
  std::size_t images = 0;
  double seconds = 0;
  std::map<std::string, double> metrics;  // including peak_rss_mb
  std::vector<StageReport> stages;

  double PeakRssMb() const;
};

std::string TileReportPath(const std::string& tile_dir);

// Writes DIR/tile_report.json atomically.
void WriteTileReport(const std::string& tile_dir, const TileReport& report);

// The report of a tile folder; nullopt when there is none or it cannot be
// read (a tile killed before it finished, a damaged file): either way the
// tile has not finished.
std::optional<TileReport> ReadTileReport(const std::string& tile_dir);

// The stages' reports as tile_report.json's "stages" holds them.
nlohmann::json StageReportsJson(const std::vector<StageReport>& reports);

std::optional<StageStatus> StageStatusFromString(const std::string& text);

// Another stage's record (sfm_report.json, tiles.json) as JSON, or null when it
// is missing or cannot be read: for a report that can do without what it adds.
nlohmann::json ReadRecordOrNull(const std::string& path);

}  // namespace skyfall
