// The merge of a city's finished tiles into one scene with LOD, a city DSM
// and a seam metric.
#pragma once

#include <string>

#include "core/aoi.h"
#include "core/stage.h"
#include "merge/seam.h"
#include "pipeline/run_options.h"

namespace skyfall {

struct MergeSummary {
  std::string scene_path;
  // What the DSMs are rasterized from (DsmOptions::source): scene_path, or
  // surface.ply beside it, the tiles' reconstructions stitched alike, when
  // some tile's synthesis stage changed its scene.
  std::string surface_path;
  std::string surface_source;  // "final" or "reconstruction"
  GeodeticPoint enu_origin;
  int epsg = 0;
  std::size_t tiles_merged = 0, tiles_missing = 0;
  SeamMetric seam;
  int lod_levels = 0;      // levels written, the finest included
  StageReport report;      // metrics: the stitch counts and seam_ratio
};

// Merges the finished tiles of TILES/tiles.json into out_dir: scene.ply,
// lod_<k>.ply + lod.json, frame.json, dsm_city.tif and merge_report.json
// (stitch counts, seam metric, LOD levels). With dsm.source
// "reconstruction" and tiles whose synthesis stage ran, their
// reconstructions are stitched too, into surface.ply, and the city DSM and
// its seam metric come from that. Tiles without a finished scene are left to
// their neighbours (warned); none at all is an Error.
MergeSummary MergeTiles(const std::string& tiles_dir, const std::string& out_dir, const MergeOptions& options,
                        const DsmOptions& dsm, Progress& progress);

}  // namespace skyfall
