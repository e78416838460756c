// DFC2019 ingestion: scans a Track 3 tree (Track3-RGB / Track3-RGB-crops,
// Track3-Truth, optional Sat-NeRF JSONs), groups images by AOI and builds one
// AoiCatalog per AOI, written as OUT/<AOI>/aoi.json.
#pragma once

#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/option_range.h"
#include "core/stage.h"
#include "ingest/radiometry.h"

namespace skyfall {

struct IngestOptions {
  std::vector<std::string> aois;  // ingest only these AOIs; empty = every AOI found
  bool verify_pixels = true;      // read every pixel once to catch corrupt rasters early
  double height_margin_m = 5.0;   // [m] added on both sides of a truth/JSON height range
  // [m] half-width of the height range used when only the RPC is known,
  // around its HEIGHT_OFF (clamped to HEIGHT_SCALE).
  double rpc_height_half_range_m = 150.0;
  // [m] orbit height for the off-nadir angle (WorldView-3 flies at ~617 km).
  double nominal_orbit_height_m = 617000.0;
  // [m] vertical separation of the two points that define the viewing ray.
  double view_ray_height_step_m = 100.0;
  RadiometryOptions radiometry;   // how each image's values map to [0, 1] (recorded per image)
  // Throws Error("ingest", field, ...) naming the bad field.
  void Check() const;
};
template <class IO> void Visit(IO& io, IngestOptions& o) {
  io.NotAnOption(o.aois);  // which AOIs is part of the request, not of the options
  io("verify_pixels", o.verify_pixels,
     "Read every pixel once at ingest, so that corrupt rasters are found early");
  io("radiometry", o.radiometry);
  io("height_margin_m", o.height_margin_m,
     "Margin added on both sides of the height range given by the truth DSM or the Sat-NeRF JSONs", range::AtLeast(0));
  io("rpc_height_half_range_m", o.rpc_height_half_range_m,
     "Half-width of the height range around the RPC's HEIGHT_OFF when only the RPC is known (at most its "
     "HEIGHT_SCALE)", range::Above(0));
  io("nominal_orbit_height_m", o.nominal_orbit_height_m,
     "Orbit height assumed for each image's off-nadir angle", range::Above(0));
  io("view_ray_height_step_m", o.view_ray_height_step_m,
     "Vertical separation of the two points that define each image's viewing ray", range::Above(0));
}

// An image or AOI that was left out, and why.
struct Skipped {
  std::string what;    // file path or AOI name
  std::string reason;  // the error message
};

struct AoiIngestResult {
  std::string aoi;
  std::string catalog_path;  // OUT/<AOI>/aoi.json; empty when the AOI failed
  AoiCatalog catalog;
  StageReport report;              // ok, or failed with the message
  std::vector<Skipped> skipped_images;
};

struct IngestResult {
  std::vector<AoiIngestResult> aois;
  int NumIngested() const;
};

// Scans `root`, ingests each AOI independently (a bad AOI or image is
// reported and skipped) and writes the catalogs under `out_dir`. Throws Error
// only when `root` itself is unusable (missing, or no Track3-RGB folder).
IngestResult RunIngest(const IngestOptions& options, const std::string& root,
                       const std::string& out_dir, Progress& progress);

// The _DSM.txt grid description: easting and northing of the lower-left
// corner (UTM), size in pixels and GSD in metres, one number per line. Throws
// Error("ingest", path + ": <field>", ...) naming the bad field.
struct DsmTxt {
  double easting_m = 0.0;
  double northing_m = 0.0;
  int size_px = 0;
  double gsd_m = 0.0;
};
DsmTxt ParseDsmTxt(const std::string& text, const std::string& path);

}  // namespace skyfall
