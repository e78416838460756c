// The whole run as a library call: ingest a DFC2019-style tree, group
// adjacent AOIs into cities, and per city tile, run the tiles, merge with LOD,
// and export and compare each AOI's DSM.
#pragma once

#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/stage.h"
#include "pipeline/exit_codes.h"
#include "pipeline/run_options.h"

namespace skyfall {

// What to run on (the options say how).
struct RunRequest {
  std::string root;               // DFC2019-style tree
  std::string out;                // OUT/<city>/..., OUT/<AOI>/..., OUT/run_summary.json
  std::vector<std::string> aois;  // only these AOIs (empty = all)
  double wait_lock_s = 0;         // wait this long for another run's lock on `out` (0 = refuse at once)
};

struct CityOutcome {
  std::string city;
  bool scene = false;          // a merged scene was written
  std::string report_path;     // OUT/<city>/run_report.json
  std::string error;           // why the city failed, when it did
  std::vector<double> dsm_mae_m;  // per AOI with truth, in catalog order
  bool unchanged = false;      // inputs and options as in the last finished run: nothing recomputed
  int tiles_failed = 0;
  int tiles_reset = 0;         // tiles redone because their images changed
};

struct RunSummary {
  std::vector<CityOutcome> cities;
  int aois_ingested = 0;
  int aois_failed = 0;
  double seconds = 0;
  // kExitOk when every city produced a scene with no failed tile; kExitPartial
  // when some did; kExitNothingDone when none did; kExitLocked when another
  // run holds the output folder (then lock_holder says who).
  int exit_code = kExitNothingDone;
  std::string lock_holder;
};

// [m] AOIs whose UTM footprints come closer than this form one city.
constexpr double kCityAdjacencyM = 2.0;

// Adjacent AOIs (footprints closer than kCityAdjacencyM, same UTM zone) form
// one city; cities keep the order of their first AOI.
std::vector<std::vector<AoiCatalog>> GroupCities(const std::vector<AoiCatalog>& aois);

// One city: tiles under OUT/<city>/tiles, scene under OUT/<city>/scene, DSM
// per AOI under OUT/<AOI>/, OUT/<city>/run_config.json (the options) and
// OUT/<city>/run_report.json (last, with the inputs stamp). Incremental: a
// city whose inputs and options equal those of its last finished run is not
// recomputed; a tile whose images changed is redone; finished tiles are
// skipped.
CityOutcome RunCity(const RunOptions& options, const std::vector<AoiCatalog>& aois, const std::string& out_dir,
                    Progress& progress);

// The second half of a city's run, for a city whose tiles ran elsewhere (the
// Slurm executor's finish job): reads OUT/<city>/city_job.json and
// run_config.json, then merges, exports and compares the DSMs, and writes the
// run report and the STAC catalog as RunCity does.
CityOutcome FinishCityFromFiles(const std::string& city_dir, Progress& progress);

// Checks the options, takes the output folder's lock, then runs every city
// of the request. One failing city never stops the others. Writes
// OUT/run_summary.json and the STAC catalog OUT/catalog.json. Throws Error
// for unusable options or when no AOI could be ingested.
RunSummary RunAll(const RunOptions& options, const RunRequest& request, Progress& progress);

}  // namespace skyfall
