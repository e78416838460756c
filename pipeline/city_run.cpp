#include "pipeline/city_run.h"

#include <fmt/format.h>
#include <sys/resource.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>

#include "core/atomic_file.h"
#include "core/error.h"
#include "merge/dsm.h"
#include "merge/dsm_report.h"
#include "pipeline/exit_codes.h"
#include "pipeline/merge_tiles.h"
#include "pipeline/stage_jobs.h"
#include "pipeline/tile_run.h"
#include "splat/ply.h"
#include "tiler/dfc2019.h"
#include "tiler/geo.h"
#include "tiler/tiling.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

struct UtmBox {
  Eigen::Vector2d lo, hi;
};

UtmBox FootprintUtm(const AoiCatalog& c) {
  const UtmZone zone = UtmZoneFromEpsg(c.epsg);
  UtmBox b{Eigen::Vector2d(1e18, 1e18), Eigen::Vector2d(-1e18, -1e18)};
  for (const auto& p : c.footprint_lonlat) {
    const Eigen::Vector2d u = UtmFromGeodetic(zone, p.x(), p.y());
    b.lo = b.lo.cwiseMin(u);
    b.hi = b.hi.cwiseMax(u);
  }
  return b;
}

json StageEntry(const std::string& stage, const std::string& status, double seconds, const std::string& message = "") {
  return {{"stage", stage}, {"status", status}, {"seconds", seconds}, {"message", message}};
}

json Finite(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

double PeakChildRssMb() {
  rusage usage{};
  getrusage(RUSAGE_CHILDREN, &usage);
  return usage.ru_maxrss / 1024.0;
}

// Per tile: how it ended, its times and memory, its stages and decisions.
json TileEntry(const TileOutcome& o) {
  json entry = {{"tile", fs::path(o.dir).filename().string()}, {"exit_code", o.exit_code}, {"seconds", o.seconds}};
  try {
    const json report = json::parse(ReadTextFile((fs::path(o.dir) / "tile_report.json").string()));
    entry["status"] = report.at("status");
    entry["message"] = report.at("message");
    entry["tile_seconds"] = report.at("seconds");
    entry["peak_rss_mb"] = report.at("metrics").value("peak_rss_mb", 0.0);
    entry["stages"] = report.at("stages");
    entry["decisions"] = report.value("decisions", json::object());
  } catch (const std::exception&) {
    entry["status"] = "failed";
    entry["message"] = o.message;
  }
  return entry;
}

// The dense heights of every finished tile as opaque Gaussians (one per cell:
// half a cell wide, flat), so they go through the same DSM export as the
// trained scene and the two can be compared side by side: all cells, and the
// matched ones alone (the filled ones left out). Tiles share the city frame;
// in their overlaps both copies are kept (the export takes the surface).
struct DenseClouds {
  GaussianCloud all, measured;
  std::size_t cells = 0, filled = 0;
};

DenseClouds DenseCellsAsGaussians(const std::vector<std::string>& tile_dirs) {
  DenseClouds out;
  for (const std::string& dir : tile_dirs) {
    const fs::path ply = fs::path(dir) / "sfm" / "dense.ply";
    if (!fs::exists(ply)) continue;
    const DenseCells cells = ReadDenseCells(ply.string());
    const float half_cell = static_cast<float>(std::log(0.5 * cells.cell_m));
    for (std::size_t k = 0; k < cells.points.size(); ++k) {
      ++out.cells;
      out.filled += cells.filled[k];
      std::array<float, 3 * kShCoeffsPerChannel> sh{};
      for (int c = 0; c < 3; ++c) sh[c * kShCoeffsPerChannel] = static_cast<float>(ShDcFromColour(cells.colours[k][c]));
      for (GaussianCloud* cloud : {&out.all, &out.measured}) {
        if (cloud == &out.measured && cells.filled[k]) continue;
        cloud->means.push_back(cells.points[k]);
        cloud->log_scales.emplace_back(half_cell, half_cell, std::log(0.05f));
        cloud->rotations.emplace_back(1.0f, 0.0f, 0.0f, 0.0f);
        cloud->opacity_logits.push_back(4.6f);  // opacity 0.99: opaque
        cloud->sh.push_back(sh);
      }
    }
  }
  return out;
}

json ComparisonJson(const DsmComparison& c) {
  return {{"mae_m", c.mae_m}, {"rmse_m", c.rmse_m}, {"median_abs_m", c.median_abs_m}, {"nmad_m", c.nmad_m},
          {"completeness", c.completeness}, {"within_1m", c.within_fraction}};
}

// Exports and compares the DSM of every AOI with truth; returns their entries.
// Beside the trained scene's figures: those of the dense heights alone, and of
// their matched cells alone (the filled ones left out).
json CompareAois(const RunOptions& options, const std::vector<AoiCatalog>& aois, const MergeSummary& merged,
                 const std::vector<std::string>& tile_dirs, const std::string& out_dir, json* stages,
                 CityOutcome* outcome, Progress& progress) {
  json dsm = json::array();
  const GaussianCloud scene = ReadGaussiansPly(merged.scene_path);
  const DenseClouds dense_clouds = DenseCellsAsGaussians(tile_dirs);
  const GaussianCloud& dense = dense_clouds.all;
  const GaussianCloud& measured = dense_clouds.measured;
  const std::size_t filled = dense_clouds.filled, cells = dense_clouds.cells;
  for (const AoiCatalog& a : aois) {
    if (!a.truth) continue;
    Stopwatch clock;
    const fs::path aoi_dir = fs::path(out_dir) / a.aoi;
    const TruthDsm truth = ReadTruthDsm(*a.truth);
    DsmGrid pred;
    const DsmComparison c = CompareSceneWithTruth(scene, merged.enu_origin, *a.truth, truth, options.dsm.compare, &pred,
                                                  options.dsm.export_options);
    WriteDsm((aoi_dir / "dsm.tif").string(), pred);
    WriteDsmComparison(c, truth.dsm, options.dsm.compare,
                       {(aoi_dir / "dsm.tif").string(), a.truth->dsm_path, a.truth->cls_path},
                       (aoi_dir / "dsm_compare").string());
    progress.Info(fmt::format("[{}] DSM vs truth: MAE {:.2f} m, RMSE {:.2f} m, completeness {:.1f}%", a.aoi, c.mae_m,
                              c.rmse_m, 100 * c.completeness));
    json entry = ComparisonJson(c);
    entry["aoi"] = a.aoi;
    entry["dsm"] = (aoi_dir / "dsm.tif").string();
    entry["report"] = (aoi_dir / "dsm_compare/report.json").string();
    if (dense.size() > 0) {
      DsmGrid unused;
      const DsmComparison d = CompareSceneWithTruth(dense, merged.enu_origin, *a.truth, truth, options.dsm.compare,
                                                    &unused, options.dsm.export_options);
      const DsmComparison m = CompareSceneWithTruth(measured, merged.enu_origin, *a.truth, truth,
                                                    options.dsm.compare, &unused, options.dsm.export_options);
      entry["dense"] = ComparisonJson(d);
      entry["dense"]["filled_cell_fraction"] = cells ? static_cast<double>(filled) / cells : 0.0;
      entry["dense_measured_only"] = ComparisonJson(m);
      progress.Info(fmt::format("[{}] dense heights alone: MAE {:.2f} m, completeness {:.1f}% ({:.1f}% of cells "
                                "filled; matched cells alone: MAE {:.2f} m, completeness {:.1f}%)",
                                a.aoi, d.mae_m, 100 * d.completeness, cells ? 100.0 * filled / cells : 0.0, m.mae_m,
                                100 * m.completeness));
    }
    dsm.push_back(entry);
    outcome->dsm_mae_m.push_back(c.mae_m);
    stages->push_back(StageEntry("dsm " + a.aoi, "ok", clock.Seconds()));
  }
  return dsm;
}

}  // namespace

std::vector<std::vector<AoiCatalog>> GroupCities(const std::vector<AoiCatalog>& aois) {
  std::vector<int> parent(aois.size());
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> find = [&](int i) { return parent[i] == i ? i : parent[i] = find(parent[i]); };
  std::vector<UtmBox> boxes;
  for (const auto& a : aois) boxes.push_back(FootprintUtm(a));
  for (std::size_t i = 0; i < aois.size(); ++i) {
    for (std::size_t j = i + 1; j < aois.size(); ++j) {
      if (aois[i].epsg != aois[j].epsg) continue;
      const Eigen::Vector2d gap = (boxes[i].lo - boxes[j].hi).cwiseMax(boxes[j].lo - boxes[i].hi);
      if (gap.maxCoeff() < kCityAdjacencyM) parent[find(static_cast<int>(i))] = find(static_cast<int>(j));
    }
  }
  std::map<int, std::vector<AoiCatalog>> groups;
  std::vector<int> order;
  for (std::size_t i = 0; i < aois.size(); ++i) {
    const int root = find(static_cast<int>(i));
    if (!groups.count(root)) order.push_back(root);
    groups[root].push_back(aois[i]);
  }
  std::vector<std::vector<AoiCatalog>> out;
  for (int root : order) out.push_back(std::move(groups[root]));
  return out;
}

CityOutcome RunCity(const RunOptions& options, const std::vector<AoiCatalog>& aois, const std::string& out_dir,
                    Progress& progress) {
  options.Check();
  Stopwatch total, clock;
  json stages = json::array();
  const TilePlan plan = PlanTiles(options.tiling, aois);
  CityOutcome outcome;
  outcome.city = plan.city;
  const fs::path city_dir = fs::path(out_dir) / plan.city;
  outcome.report_path = (city_dir / "run_report.json").string();
  progress.Info(fmt::format("[{}] {} AOI(s), {}x{} tiles of {} m", plan.city, aois.size(), plan.grid.cols,
                            plan.grid.rows, plan.grid.tile_m));
  const TilingResult tiles = WriteTiles(plan, (city_dir / "tiles").string(), progress);
  stages.push_back(StageEntry("tile", "ok", clock.Seconds()));
  // The tiles' processes read the options from this file; it is also the
  // record of what this city was run with.
  const std::string config_path = (city_dir / "run_config.json").string();
  WriteFileIfChanged(config_path, RunOptionsToJson(options));

  clock = Stopwatch();
  const std::vector<TileOutcome> outcomes = RunTiles(tiles.tile_dirs, options, config_path, progress);
  json tile_list = json::array();
  int failed = 0;
  for (const TileOutcome& o : outcomes) {
    failed += o.exit_code != kExitOk && o.exit_code != kExitDegenerate;
    tile_list.push_back(TileEntry(o));
  }
  stages.push_back(StageEntry("tiles", failed ? "partial" : "ok", clock.Seconds(),
                              failed ? std::to_string(failed) + " tile(s) failed" : ""));
  json report = {{"city", plan.city}, {"options", json::parse(RunOptionsToJson(options))}, {"tiles", tile_list}};
  json aoi_names = json::array();
  for (const auto& a : aois) aoi_names.push_back(a.aoi);
  report["aois"] = aoi_names;

  clock = Stopwatch();
  MergeSummary merged;
  try {
    merged = MergeTiles((city_dir / "tiles").string(), (city_dir / "scene").string(), options.merge,
                        options.dsm.export_options, progress);
    stages.push_back(StageEntry("merge", "ok", clock.Seconds()));
  } catch (const Error& e) {
    progress.Warn("[" + plan.city + "] merge: " + e.what());
    stages.push_back(StageEntry("merge", "failed", clock.Seconds(), e.what()));
    outcome.error = e.what();
    report["stages"] = stages;
    report["seconds"] = total.Seconds();
    WriteFileAtomic(outcome.report_path, report.dump(2) + "\n");
    return outcome;
  }
  outcome.scene = true;
  report["dsm"] = CompareAois(options, aois, merged, tiles.tile_dirs, out_dir, &stages, &outcome, progress);
  report["stages"] = stages;
  report["merge"] = merged.report.metrics;
  report["decisions"] = {{"lod_levels", {{"levels", merged.lod_levels},
                                         {"why", fmt::format("a coarser level is kept while it has at most {:.0f}% of the "
                                                             "previous level's Gaussians, up to {} levels",
                                                             100 * options.merge.lod.min_reduction,
                                                             options.merge.lod.max_levels)}}}};
  report["seam"] = {{"ratio", Finite(merged.seam.ratio)},
                    {"boundary_mean_step_m", Finite(merged.seam.boundary_mean_step_m)},
                    {"interior_mean_step_m", Finite(merged.seam.interior_mean_step_m)}};
  report["scene"] = merged.scene_path;
  report["peak_tile_rss_mb"] = PeakChildRssMb();
  report["seconds"] = total.Seconds();
  WriteFileAtomic(outcome.report_path, report.dump(2) + "\n");
  progress.Info(fmt::format("[{}] done in {:.0f} s -> {}", plan.city, total.Seconds(), city_dir.string()));
  return outcome;
}

RunSummary RunAll(const RunOptions& options, const RunRequest& request, Progress& progress) {
  options.Check();
  if (request.root.empty()) throw Error("run", "root", "no input folder given");
  if (request.out.empty()) throw Error("run", "out", "no output folder given");
  Stopwatch clock;
  RunSummary summary;
  IngestOptions ingest = options.ingest;
  ingest.aois = request.aois;
  const IngestResult ingested = RunIngest(ingest, request.root, (fs::path(request.out) / "catalogs").string(), progress);
  std::vector<AoiCatalog> catalogs;
  for (const auto& a : ingested.aois) {
    if (a.report.status == StageStatus::kOk) {
      catalogs.push_back(a.catalog);
    } else {
      progress.Warn(a.aoi + ": ingest failed: " + a.report.message);
      ++summary.aois_failed;
    }
  }
  summary.aois_ingested = static_cast<int>(catalogs.size());
  if (catalogs.empty()) throw Error("run", request.root, "no AOI could be ingested");
  const auto cities = GroupCities(catalogs);
  progress.Info(fmt::format("run: {} AOI(s) in {} cit{} ({:.1f} s ingest)", catalogs.size(), cities.size(),
                            cities.size() == 1 ? "y" : "ies", clock.Seconds()));
  json list = json::array();
  int done = 0;
  for (std::size_t k = 0; k < cities.size(); ++k) {
    progress.Info(fmt::format("run: city {}/{}", k + 1, cities.size()));
    CityOutcome city;
    try {
      city = RunCity(options, cities[k], request.out, progress);
    } catch (const Error& e) {
      progress.Warn(std::string("run: ") + e.what());  // one bad city never sinks the batch
      city.city = cities[k].front().aoi;
      city.error = e.what();
    }
    done += city.scene;
    list.push_back({{"city", city.city}, {"scene", city.scene}, {"report", city.report_path}, {"error", city.error}});
    summary.cities.push_back(std::move(city));
  }
  summary.seconds = clock.Seconds();
  summary.exit_code = done > 0 ? kExitOk : kExitBadInput;
  WriteFileAtomic((fs::path(request.out) / "run_summary.json").string(),
                  json{{"root", request.root}, {"cities", list}, {"seconds", summary.seconds}}.dump(2) + "\n");
  progress.Info(fmt::format("run: {} of {} cities reconstructed in {:.0f} s", done, cities.size(), summary.seconds));
  return summary;
}

}  // namespace skyfall
