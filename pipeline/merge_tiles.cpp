#include "pipeline/merge_tiles.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>

#include "catalogs/aoi_catalog.h"
#include "catalogs/tile_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "products/dsm.h"
#include "merge/lod.h"
#include "merge/stitch.h"
#include "pipeline/stage_jobs.h"
#include "pipeline/tile_report.h"
#include "splat/ply.h"
#include "ingest/geo.h"
#include "tiling/tiling.h"

namespace skyfall {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// A tile's DSM rendered as the merge's own DSM is (median depth from a
// nadir camera) on a UTM grid over its extent, read back at ENU points.
SurfaceHeight RenderedSurface(const TileSpec& tile, const GaussianCloud& cloud, int epsg, double gsd_m,
                              const DsmExportOptions& dsm_options) {
  auto dsm = std::make_shared<DsmGrid>(GridCovering(tile.extent, tile.enu_origin, epsg, gsd_m));
  RasterizeDsm(cloud, tile.enu_origin, dsm_options, dsm.get());
  const EnuFrame frame(tile.enu_origin);
  const UtmZone zone = UtmZoneFromEpsg(epsg);
  return [dsm, frame, zone](double east_m, double north_m) {
    const GeodeticPoint g = frame.GeodeticFromEnu({east_m, north_m, 0.0});
    const Eigen::Vector2d utm = UtmFromGeodetic(zone, g.lon_deg, g.lat_deg);
    const double col = std::floor((utm.x() - dsm->upper_left_easting_m) / dsm->gsd_m);
    const double row = std::floor((dsm->upper_left_northing_m - utm.y()) / dsm->gsd_m);
    if (col < 0 || row < 0 || col >= dsm->width_px || row >= dsm->height_px) return std::nanf("");
    return dsm->At(static_cast<int>(col), static_cast<int>(row));
  };
}

// Seam lines on the tiles' rendered surfaces (on their Gaussian centres
// when no CRS is known).
TileOwnership PlanOwnership(const MergeOptions& options, const DsmExportOptions& dsm_options,
                            const TileSource& tiles, int epsg) {
  const SeamLineOptions& o = options.stitch.seam_lines;
  if (!o.enabled || epsg == 0) return PlanSeamLinesOnCentres(o, tiles);
  std::vector<SurfaceHeight> surfaces;
  for (std::size_t k = 0; k < tiles.size(); ++k) {
    tiles.visit(k, [&](const GaussianCloud& cloud) {
      surfaces.push_back(RenderedSurface(tiles.specs[k], cloud, epsg, o.cell_m, dsm_options));
    });
  }
  return PlanSeamLines(o, tiles.specs, surfaces);
}

json ReadTileIndex(const std::string& tiles_dir) {
  const fs::path index_path = fs::path(tiles_dir) / "tiles.json";
  try {
    return json::parse(ReadTextFile(index_path.string()));
  } catch (const json::exception& e) {
    throw Error("merge", index_path.string(), std::string("not valid JSON: ") + e.what());
  }
}

// The finished tiles: their specs and scene files; per tile, its
// reconstruction's surface (TileSurfacePath) when the DSMs come from it and
// it differs from the tile's scene (the synthesis stage ran, or training
// kept a surface at train.surface_at), else empty; and the tiles that have no
// finished scene. Nothing is read beyond the tiles' small JSON files: the
// stitch reads each tile's Gaussians when it needs them.
struct TileScenes {
  std::vector<TileSpec> specs;
  std::vector<std::string> scenes;
  std::vector<std::string> reconstruction_of;
  std::vector<std::string> missing;
};

TileScenes FindTileScenes(const std::string& tiles_dir, const json& index, bool from_reconstruction,
                          Progress& progress, MergeSummary* summary) {
  TileScenes found;
  for (const json& t : index.at("tiles")) {
    const fs::path dir = fs::path(tiles_dir) / t.at("id").get<std::string>();
    const TileSpec spec = ReadTileSpec((dir / "tile.json").string());
    if (summary->epsg == 0 && fs::exists(dir / "aoi.json")) summary->epsg = ReadAoiCatalog((dir / "aoi.json").string()).epsg;
    const fs::path scene = TileScenePath(dir.string());
    const std::optional<TileReport> report = ReadTileReport(dir.string());
    if (report && report->status == StageStatus::kOk && fs::exists(scene)) {
      found.specs.push_back(spec);
      found.scenes.push_back(scene.string());
      const std::string reconstruction = TileSurfacePath(dir.string());
      const bool differs = from_reconstruction && scene.string() != reconstruction && fs::exists(reconstruction);
      found.reconstruction_of.push_back(differs ? reconstruction : std::string());
    } else {
      found.missing.push_back(spec.id);
      progress.Warn("merge: tile " + spec.id + " has no finished scene; its area is left to its neighbours");
    }
  }
  return found;
}

// True when some tile's surface differs from its scene and the DSMs come
// from the reconstructions.
bool SurfaceDiffers(const TileScenes& found) {
  return std::any_of(found.reconstruction_of.begin(), found.reconstruction_of.end(),
                     [](const std::string& p) { return !p.empty(); });
}

// The tiles' scenes (or their reconstructions), each read from its file
// when the stitch visits it; every visit advances `progress`.
TileSource TileFiles(const TileScenes& found, bool reconstructions, Progress& progress) {
  TileSource source;
  source.specs = found.specs;
  auto visits = std::make_shared<std::size_t>(0);
  source.visit = [&found, reconstructions, &progress, visits](std::size_t k, const CloudUser& use) {
    const std::string& path = reconstructions && !found.reconstruction_of[k].empty() ? found.reconstruction_of[k]
                                                                                      : found.scenes[k];
    use(ReadGaussiansPly(path));
    progress.Advance(++*visits, found.specs[k].id);
  };
  return source;
}

// Stitches the tiles of `source` into the PLY at `path`, streamed: seam
// lines on their rendered surfaces, then the cores, then the overlap
// bands; each pass reads each tile once.
StitchResult StitchToFile(const MergeOptions& options, const DsmExportOptions& dsm_options,
                          const GeodeticPoint& city_origin, int epsg, const TileSource& source,
                          const std::string& path, const std::string& what, Progress& progress) {
  // Seam lines read every tile once more, unless they are off (or no tile
  // reaches them).
  const bool plans_seams = options.stitch.seam_lines.enabled && source.size() > 0;
  progress.Begin("merge: stitching " + what + (plans_seams ? " (seam lines, cores, overlaps)" : " (cores, overlaps)"),
                 (plans_seams ? 3 : 2) * source.size());
  const TileOwnership ownership = PlanOwnership(options, dsm_options, source, epsg);
  GaussiansPlyWriter file(path);
  StitchResult stitched = StitchTiles(options.stitch, city_origin, source, ownership,
                                      [&](std::size_t, const GaussianCloud& cloud, std::size_t i) { file.Add(cloud, i); });
  file.Finish();
  progress.End();
  return stitched;
}

json LodLevelsJson(const std::vector<LodLevel>& lod) {
  json levels = json::array();
  for (const LodLevel& l : lod) {
    levels.push_back({{"level", l.level}, {"count", l.count}, {"voxel_m", l.voxel_m},
                      {"geometric_error_m", l.geometric_error_m}});
  }
  return levels;
}

void WriteMergeReport(const std::string& out_dir, const json& index, const StitchResult& stitched,
                      const json& levels, const std::vector<std::string>& missing, const MergeSummary& summary) {
  auto finite = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  const std::string city = index.at("city").get<std::string>();
  json borders = json::array();
  for (const BorderSeam& b : summary.seam.borders) {
    borders.push_back({{"tiles", {TileId(city, b.tile_a.x(), b.tile_a.y()), TileId(city, b.tile_b.x(), b.tile_b.y())}},
                       {"mean_step_m", b.mean_step_m},
                       {"ratio", finite(b.mean_step_m / summary.seam.interior_mean_step_m)},
                       {"pairs", b.pairs}});
  }
  const json doc = {{"city", index.at("city")},
                    {"tiles_merged", summary.tiles_merged},
                    {"tiles_missing", missing},
                    {"stitch", stitched.report.metrics},
                    {"seam", {{"boundary_mean_step_m", finite(summary.seam.boundary_mean_step_m)},
                              {"interior_mean_step_m", finite(summary.seam.interior_mean_step_m)},
                              {"ratio", finite(summary.seam.ratio)},
                              {"boundary_pairs", summary.seam.boundary_pairs},
                              {"interior_pairs", summary.seam.interior_pairs},
                              {"borders", borders}}},
                    {"lod", levels},
                    {"dsm_source", summary.surface_source},
                    {"seconds", summary.report.seconds}};
  WriteFileAtomic((fs::path(out_dir) / "merge_report.json").string(), doc.dump(2) + "\n");
}

}  // namespace

MergeSummary MergeTiles(const std::string& tiles_dir, const std::string& out_dir, const MergeOptions& options,
                        const DsmOptions& dsm, Progress& progress) {
  Stopwatch clock;
  options.Check();
  dsm.Check();
  const DsmExportOptions& dsm_options = dsm.export_options;
  MergeSummary summary;
  summary.report.stage = "merge";
  const json index = ReadTileIndex(tiles_dir);
  const TileScenes found =
      FindTileScenes(tiles_dir, index, dsm.source == DsmSource::kReconstruction, progress, &summary);
  if (found.specs.empty()) throw Error("merge", tiles_dir, "no finished tile to merge (run `skyfall run-tile` first)");
  const json& o = index.at("enu_origin");
  summary.enu_origin = {o.at("lon_deg").get<double>(), o.at("lat_deg").get<double>(), o.at("height_m").get<double>()};
  fs::create_directories(out_dir);

  // Everything below streams: memory holds one tile, one LOD block or one
  // DSM block at a time, never the city's Gaussians.
  summary.scene_path = (fs::path(out_dir) / "scene.ply").string();
  const StitchResult stitched = StitchToFile(options, dsm_options, summary.enu_origin, summary.epsg,
                                             TileFiles(found, false, progress), summary.scene_path, "the scenes",
                                             progress);
  progress.Info("merge: building the LOD levels");
  const std::vector<LodLevel> levels = WriteLodLevels(
      options.lod, [&](const GaussianChunkVisitor& visit) { ForEachGaussiansPlyChunk(summary.scene_path, visit); },
      out_dir);
  summary.surface_path = summary.scene_path;
  summary.surface_source = "final";
  std::optional<StitchResult> surface_stitched;
  const fs::path surface_ply = fs::path(out_dir) / "surface.ply";
  if (SurfaceDiffers(found)) {
    surface_stitched = StitchToFile(options, dsm_options, summary.enu_origin, summary.epsg,
                                    TileFiles(found, true, progress), surface_ply.string(),
                                    "the reconstructions (the DSMs' surface)", progress);
    summary.surface_path = surface_ply.string();
    summary.surface_source = "reconstruction";
  } else {
    fs::remove(surface_ply);  // an earlier run's would no longer match the scene
  }
  summary.tiles_merged = found.specs.size();
  const StitchResult& surface = surface_stitched ? *surface_stitched : stitched;

  // Seam metric on a city DSM rendered from that surface, in blocks, each
  // from the Gaussians that can reach it.
  DsmGrid city = GridCovering(BoxFromJson(index.at("bounds")), summary.enu_origin, summary.epsg, options.seam_gsd_m);
  RasterizeDsmInBlocks([&](const GaussianFilter& keep) { return ReadGaussiansPly(summary.surface_path, keep); },
                       summary.enu_origin, dsm_options, &city);
  WriteDsm((fs::path(out_dir) / "dsm_city.tif").string(), city);
  summary.seam = MeasureSeams(city, surface.ownership, summary.enu_origin);
  summary.tiles_missing = found.missing.size();
  summary.lod_levels = static_cast<int>(levels.size());
  const json frame = {{"enu_origin", o}, {"epsg", summary.epsg}, {"city", index.at("city")}};
  WriteFileAtomic((fs::path(out_dir) / "frame.json").string(), frame.dump(2) + "\n");
  summary.report.seconds = clock.Seconds();
  summary.report.metrics = stitched.report.metrics;
  summary.report.metrics["seam_ratio"] = summary.seam.ratio;
  WriteMergeReport(out_dir, index, stitched, LodLevelsJson(levels), found.missing, summary);
  return summary;
}

}  // namespace skyfall
