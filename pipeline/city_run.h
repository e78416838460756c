// The whole run as a library call: ingest a DFC2019-style tree, group
// adjacent AOIs into cities, and per city tile, run the tiles, merge with LOD,
// and export and compare each AOI's DSM.
#pragma once

#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/stage.h"
#include "pipeline/run_options.h"

namespace skyfall {

// What to run on (the options say how).
struct RunRequest {
  std::string root;               // DFC2019-style tree
  std::string out;                // OUT/<city>/..., OUT/<AOI>/..., OUT/run_summary.json
  std::vector<std::string> aois;  // only these AOIs (empty = all)
};

struct CityOutcome {
  std::string city;
  bool scene = false;          // a merged scene was written
  std::string report_path;     // OUT/<city>/run_report.json
  std::string error;           // why the city failed, when it did
  std::vector<double> dsm_mae_m;  // per AOI with truth, in catalog order
};

struct RunSummary {
  std::vector<CityOutcome> cities;
  int aois_ingested = 0;
  int aois_failed = 0;
  double seconds = 0;
  int exit_code = 1;  // kExitOk when at least one city produced a scene, else kExitBadInput
};

// [m] AOIs whose UTM footprints come closer than this form one city.
constexpr double kCityAdjacencyM = 2.0;

// Adjacent AOIs (footprints closer than kCityAdjacencyM, same UTM zone) form
// one city; cities keep the order of their first AOI.
std::vector<std::vector<AoiCatalog>> GroupCities(const std::vector<AoiCatalog>& aois);

// One city: tiles under OUT/<city>/tiles, scene under OUT/<city>/scene, DSM
// per AOI under OUT/<AOI>/, OUT/<city>/run_config.json (the options) and
// OUT/<city>/run_report.json (last). Resumable: finished tiles are skipped.
CityOutcome RunCity(const RunOptions& options, const std::vector<AoiCatalog>& aois, const std::string& out_dir,
                    Progress& progress);

// Checks the options, then runs every city of the request. One failing city
// never stops the others. Writes OUT/run_summary.json. Throws Error for
// unusable options or when no AOI could be ingested.
RunSummary RunAll(const RunOptions& options, const RunRequest& request, Progress& progress);

}  // namespace skyfall
