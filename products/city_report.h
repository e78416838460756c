// run_report.json, what a city's run writes last: its tiles, the city
// stages, and once the merge succeeded the scene, the products and the
// inputs the next run compares. One writer and one reader; the resume check,
// the Slurm finish and `skyfall status` go through them.
#pragma once

#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace skyfall {

struct CityReport {
  static constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();  // a figure not (yet) known
  std::string city;
  nlohmann::json options;                           // RunOptionsToJson of the run
  nlohmann::json tiles = nlohmann::json::array();   // per tile: how it ended, its times, stages and decisions
  std::vector<std::string> aois;
  nlohmann::json stages = nlohmann::json::array();  // the city's stages: merge, one per AOI's products, 3dtiles
  double seconds = kUnknown;                        // the city's wall time so far [s]

  // Set once the merge succeeded: a report without a scene is a failed city,
  // and the fields below are written only with one.
  std::optional<std::string> scene;                    // the merged scene's PLY
  nlohmann::json dsm = nlohmann::json::array();        // per AOI with truth: its comparison ("aoi", "mae_m", ...)
  nlohmann::json products = nlohmann::json::array();   // files per AOI
  nlohmann::json city_products;                        // the city's mosaics
  std::optional<nlohmann::json> tiles3d;               // the 3D Tiles export, when it ran and succeeded
  nlohmann::json merge;                                // the merge's metrics
  nlohmann::json decisions;                            // what the merge decided and why
  nlohmann::json seam;                                 // the seam metric
  double peak_tile_rss_mb = kUnknown;
  nlohmann::json inputs;  // what the next run compares to skip an unchanged city

  // True when a tile's entry says it failed (or says nothing).
  bool AnyTileFailed() const;
  // The DSM MAE [m] of `aoi`'s comparison; nullopt when it has none or it is
  // not a number.
  std::optional<double> DsmMaeM(const std::string& aoi) const;
  // Every comparison's MAE [m] in report order; nullopt when one is not a number.
  std::optional<std::vector<double>> DsmMaesM() const;
};

std::filesystem::path CityReportPath(const std::filesystem::path& city_dir);

// Writes the report atomically.
void WriteCityReport(const std::string& path, const CityReport& report);

// The report at `path`; nullopt when there is none or it cannot be read
// (a city stopped before it finished, a damaged file), and then `why`, when
// given, says which.
std::optional<CityReport> ReadCityReport(const std::string& path, std::string* why = nullptr);

}  // namespace skyfall
