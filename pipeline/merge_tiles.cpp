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
SurfaceHeight RenderedSurface(const TileCloud& tile, int epsg, double gsd_m, const DsmExportOptions& dsm_options) {
  auto dsm = std::make_shared<DsmGrid>(GridCovering(tile.tile.extent, tile.tile.enu_origin, epsg, gsd_m));
  RasterizeDsm(tile.cloud, tile.tile.enu_origin, dsm_options, dsm.get());
  const EnuFrame frame(tile.tile.enu_origin);
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
                            const std::vector<TileCloud>& clouds, int epsg, Progress& progress) {
  const SeamLineOptions& o = options.stitch.seam_lines;
  if (!o.enabled || epsg == 0) return PlanSeamLinesOnCentres(o, clouds);
  std::vector<TileSpec> specs;
  std::vector<SurfaceHeight> surfaces;
  progress.Begin("merge: rendering tile surfaces for the seam lines", clouds.size());
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    specs.push_back(clouds[k].tile);
    surfaces.push_back(RenderedSurface(clouds[k], epsg, o.cell_m, dsm_options));
    progress.Advance(k + 1, clouds[k].tile.id);
  }
  progress.End();
  return PlanSeamLines(o, specs, surfaces);
}

json ReadTileIndex(const std::string& tiles_dir) {
  const fs::path index_path = fs::path(tiles_dir) / "tiles.json";
  try {
    return json::parse(ReadTextFile(index_path.string()));
  } catch (const json::exception& e) {
    throw Error("merge", index_path.string(), std::string("not valid JSON: ") + e.what());
  }
}

// The finished tiles' scenes; per tile, its reconstruction when the DSMs
// come from it and it differs from the tile's scene (the synthesis stage
// ran), else empty; and the tiles that have no finished scene.
struct TileScenes {
  std::vector<TileCloud> clouds;
  std::vector<std::string> reconstruction_of;
  std::vector<std::string> missing;
};

TileScenes ReadTileScenes(const std::string& tiles_dir, const json& index, bool from_reconstruction,
                          Progress& progress, MergeSummary* summary) {
  TileScenes read;
  const json& tiles = index.at("tiles");
  progress.Begin("merge: reading tiles", tiles.size());
  std::size_t k = 0;
  for (const json& t : tiles) {
    const fs::path dir = fs::path(tiles_dir) / t.at("id").get<std::string>();
    const TileSpec spec = ReadTileSpec((dir / "tile.json").string());
    if (summary->epsg == 0 && fs::exists(dir / "aoi.json")) summary->epsg = ReadAoiCatalog((dir / "aoi.json").string()).epsg;
    const fs::path scene = TileScenePath(dir.string());
    const std::optional<TileReport> report = ReadTileReport(dir.string());
    if (report && report->status == StageStatus::kOk && fs::exists(scene)) {
      read.clouds.push_back({spec, ReadGaussiansPly(scene.string())});
      const std::string reconstruction = TileReconstructionPath(dir.string());
      const bool differs = from_reconstruction && scene.string() != reconstruction && fs::exists(reconstruction);
      read.reconstruction_of.push_back(differs ? reconstruction : std::string());
    } else {
      read.missing.push_back(spec.id);
      progress.Warn("merge: tile " + spec.id + " has no finished scene; its area is left to its neighbours");
    }
    progress.Advance(++k, spec.id);
  }
  progress.End();
  return read;
}

// True when some tile's reconstruction differs from its scene (its synthesis
// stage ran) and the DSMs come from the reconstructions.
bool SurfaceDiffers(const TileScenes& read) {
  return std::any_of(read.reconstruction_of.begin(), read.reconstruction_of.end(),
                     [](const std::string& p) { return !p.empty(); });
}

// The surface the DSMs come from: the reconstructions stitched alike when
// some tile's synthesis stage changed its scene (written to surface.ply),
// else none (the merged scene is the surface). The tiles' scenes are not
// needed past the stitch: they become the reconstructions where those are
// the same, so one city's worth of tiles is held at a time.
std::optional<StitchResult> StitchReconstructions(const MergeOptions& options, const DsmExportOptions& dsm_options,
                                                  const std::string& out_dir, TileScenes* read, Progress& progress,
                                                  MergeSummary* summary) {
  const fs::path surface_ply = fs::path(out_dir) / "surface.ply";
  if (!SurfaceDiffers(*read)) {
    fs::remove(surface_ply);  // an earlier run's would no longer match the scene
    return std::nullopt;
  }
  std::vector<TileCloud> reconstructions;
  for (std::size_t k = 0; k < read->clouds.size(); ++k) {
    if (read->reconstruction_of[k].empty())
      reconstructions.push_back(std::move(read->clouds[k]));
    else
      reconstructions.push_back({read->clouds[k].tile, ReadGaussiansPly(read->reconstruction_of[k])});
    read->clouds[k].cloud = GaussianCloud();
  }
  const TileOwnership ownership = PlanOwnership(options, dsm_options, reconstructions, summary->epsg, progress);
  StitchResult stitched = StitchTiles(options.stitch, summary->enu_origin, reconstructions, &ownership);
  summary->surface_path = surface_ply.string();
  WriteGaussiansPly(summary->surface_path, stitched.cloud);
  summary->surface_source = "reconstruction";
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
  TileScenes read =
      ReadTileScenes(tiles_dir, index, dsm.source == DsmSource::kReconstruction, progress, &summary);
  if (read.clouds.empty()) throw Error("merge", tiles_dir, "no finished tile to merge (run `skyfall run-tile` first)");
  const json& o = index.at("enu_origin");
  summary.enu_origin = {o.at("lon_deg").get<double>(), o.at("lat_deg").get<double>(), o.at("height_m").get<double>()};

  const TileOwnership ownership = PlanOwnership(options, dsm_options, read.clouds, summary.epsg, progress);
  StitchResult stitched = StitchTiles(options.stitch, summary.enu_origin, read.clouds, &ownership);
  fs::create_directories(out_dir);
  summary.scene_path = (fs::path(out_dir) / "scene.ply").string();
  WriteGaussiansPly(summary.scene_path, stitched.cloud);
  json lod_levels;
  {
    // Each level goes to disk as it is built; only their figures stay.
    LodWriter writer(out_dir);
    BuildLodLevels(options.lod, stitched.cloud,
                   [&](const LodLevel& level, const GaussianCloud& cloud) { writer.Add(level, cloud); });
    writer.Finish();
    lod_levels = LodLevelsJson(writer.levels());
  }
  summary.surface_path = summary.scene_path;
  summary.surface_source = "final";
  // When the DSMs come from the reconstructions, the merged scene is done
  // with (it is on disk): one city's worth of Gaussians less while they are
  // stitched.
  if (SurfaceDiffers(read)) stitched.cloud = GaussianCloud();
  const std::optional<StitchResult> surface_stitched =
      StitchReconstructions(options, dsm_options, out_dir, &read, progress, &summary);
  summary.tiles_merged = read.clouds.size();
  read.clouds.clear();  // stitched: what is left to do needs the city's cloud only
  const StitchResult& surface = surface_stitched ? *surface_stitched : stitched;

  // Seam metric on a city DSM rendered from that surface.
  DsmGrid city = GridCovering(BoxFromJson(index.at("bounds")), summary.enu_origin, summary.epsg, options.seam_gsd_m);
  // In blocks: the render's buffers follow a block, not the city.
  RasterizeDsmInBlocks([&](const GaussianFilter& keep) { return CropCloud(surface.cloud, keep); },
                       summary.enu_origin, dsm_options, &city);
  WriteDsm((fs::path(out_dir) / "dsm_city.tif").string(), city);
  summary.seam = MeasureSeams(city, surface.ownership, summary.enu_origin);
  summary.tiles_missing = read.missing.size();
  summary.lod_levels = static_cast<int>(lod_levels.size());
  const json frame = {{"enu_origin", o}, {"epsg", summary.epsg}, {"city", index.at("city")}};
  WriteFileAtomic((fs::path(out_dir) / "frame.json").string(), frame.dump(2) + "\n");
  summary.report.seconds = clock.Seconds();
  summary.report.metrics = stitched.report.metrics;
  summary.report.metrics["seam_ratio"] = summary.seam.ratio;
  WriteMergeReport(out_dir, index, stitched, lod_levels, read.missing, summary);
  return summary;
}

}  // namespace skyfall
