// skyfall run ROOT --out OUT: the whole batch for every AOI of a DFC2019 tree.
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <numeric>

#include "apps/commands.h"
#include "apps/console.h"
#include "apps/tile_jobs.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "merge/dsm.h"
#include "merge/dsm_report.h"
#include "splat/ply.h"
#include "tiler/dfc2019.h"
#include "tiler/geo.h"
#include "tiler/tiling.h"

namespace skyfall::cli {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// [m] AOIs whose UTM footprints come closer than this form one city.
constexpr double kAdjacencyM = 2.0;

struct RunArgs {
  std::string root, out;
  std::vector<std::string> aois;
  TilingOptions tiling;
  TileRunOptions tile;
  int jobs = 0;
};

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

// Adjacent AOIs (touching footprints, same UTM zone) form one city: union-find.
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
      if (gap.maxCoeff() < kAdjacencyM) parent[find(static_cast<int>(i))] = find(static_cast<int>(j));
    }
  }
  std::map<int, std::vector<AoiCatalog>> groups;
  for (std::size_t i = 0; i < aois.size(); ++i) groups[find(static_cast<int>(i))].push_back(aois[i]);
  std::vector<std::vector<AoiCatalog>> out;
  for (auto& [k, g] : groups) out.push_back(std::move(g));
  return out;
}

json StageEntry(const std::string& stage, const std::string& status, double seconds, const std::string& message = "") {
  return {{"stage", stage}, {"status", status}, {"seconds", seconds}, {"message", message}};
}

double PeakChildRssMb() {
  rusage usage{};
  getrusage(RUSAGE_CHILDREN, &usage);
  return usage.ru_maxrss / 1024.0;
}

// One city: tile, run tiles, merge, DSM per AOI. Returns true when a scene was made.
bool RunCity(const RunArgs& args, const std::vector<AoiCatalog>& aois, json* summary) {
  Stopwatch total;
  json stages = json::array();
  TilingOptions tiling = args.tiling;
  Stopwatch clock;
  const TilePlan plan = PlanTiles(tiling, aois);
  const fs::path city_dir = fs::path(args.out) / plan.city;
  spdlog::info("[{}] {} AOI(s), {}x{} tiles of {} m", plan.city, aois.size(), plan.grid.cols, plan.grid.rows,
               plan.grid.tile_m);
  ConsoleProgress progress;
  const TilingResult tiles = WriteTiles(plan, (city_dir / "tiles").string(), progress);
  stages.push_back(StageEntry("tile", "ok", clock.Seconds()));

  clock = Stopwatch();
  std::string why;
  const int jobs = ParallelTileJobs(tiles.tile_dirs, args.jobs, &why);
  spdlog::info("[{}] {}", plan.city, why);
  const std::vector<TileOutcome> outcomes = RunTilesInParallel(tiles.tile_dirs, args.tile, jobs, progress);
  json tile_list = json::array();
  int failed = 0;
  for (const TileOutcome& o : outcomes) {
    json entry = {{"tile", fs::path(o.dir).filename().string()}, {"exit_code", o.exit_code}, {"seconds", o.seconds}};
    try {
      const json report = json::parse(ReadTextFile((fs::path(o.dir) / "tile_report.json").string()));
      entry["status"] = report.at("status");
      entry["message"] = report.at("message");
      entry["tile_seconds"] = report.at("seconds");
      entry["peak_rss_mb"] = report.at("metrics").value("peak_rss_mb", 0.0);
      entry["stages"] = report.at("stages");
    } catch (const std::exception&) {
      entry["status"] = "failed";
      entry["message"] = o.message;
    }
    failed += o.exit_code != 0 && o.exit_code != kExitDegenerate;
    tile_list.push_back(entry);
  }
  stages.push_back(StageEntry("tiles", failed ? "partial" : "ok", clock.Seconds(),
                              failed ? std::to_string(failed) + " tile(s) failed" : ""));

  clock = Stopwatch();
  MergeSummary merged;
  try {
    merged = MergeTiles((city_dir / "tiles").string(), (city_dir / "scene").string(), MergeOptions{}, progress);
    stages.push_back(StageEntry("merge", "ok", clock.Seconds()));
  } catch (const Error& e) {
    spdlog::error("[{}] merge: {}", plan.city, e.what());
    stages.push_back(StageEntry("merge", "failed", clock.Seconds(), e.what()));
    *summary = {{"city", plan.city}, {"stages", stages}, {"tiles", tile_list}, {"seconds", total.Seconds()}};
    WriteFileAtomic((city_dir / "run_report.json").string(), summary->dump(2) + "\n");
    return false;
  }

  json dsm = json::array();
  const GaussianCloud scene = ReadGaussiansPly(merged.scene_path);
  for (const AoiCatalog& a : aois) {
    if (!a.truth) continue;
    clock = Stopwatch();
    const fs::path aoi_dir = fs::path(args.out) / a.aoi;
    const TruthDsm truth = ReadTruthDsm(*a.truth);
    DsmGrid pred;
    const DsmCompareOptions compare;
    const DsmComparison c = CompareSceneWithTruth(scene, merged.enu_origin, *a.truth, truth, compare, &pred);
    WriteDsm((aoi_dir / "dsm.tif").string(), pred);
    WriteDsmComparison(c, truth.dsm, compare, {(aoi_dir / "dsm.tif").string(), a.truth->dsm_path, a.truth->cls_path},
                       (aoi_dir / "dsm_compare").string());
    spdlog::info("[{}] DSM vs LiDAR: MAE {:.2f} m, RMSE {:.2f} m, completeness {:.1f}%", a.aoi, c.mae_m, c.rmse_m,
                 100 * c.completeness);
    dsm.push_back({{"aoi", a.aoi}, {"mae_m", c.mae_m}, {"rmse_m", c.rmse_m}, {"median_abs_m", c.median_abs_m},
                   {"completeness", c.completeness}, {"within_1m", c.within_fraction},
                   {"dsm", (aoi_dir / "dsm.tif").string()}, {"report", (aoi_dir / "dsm_compare/report.json").string()}});
    stages.push_back(StageEntry("dsm " + a.aoi, "ok", clock.Seconds()));
  }
  json aoi_names = json::array();
  for (const auto& a : aois) aoi_names.push_back(a.aoi);
  *summary = {{"city", plan.city},
              {"aois", aoi_names},
              {"options", {{"tile_m", tiling.tile_m}, {"overlap_m", tiling.overlap_m},
                           {"iterations", args.tile.iterations}, {"resolution_downscale", args.tile.downscale},
                           {"depth_prior", args.tile.depth_prior}, {"parallel_tiles", jobs}}},
              {"stages", stages},
              {"tiles", tile_list},
              {"merge", merged.report.metrics},
              {"seam", {{"ratio", std::isfinite(merged.seam.ratio) ? json(merged.seam.ratio) : json(nullptr)},
                        {"boundary_mean_step_m", std::isfinite(merged.seam.boundary_mean_step_m) ? json(merged.seam.boundary_mean_step_m) : json(nullptr)},
                        {"interior_mean_step_m", merged.seam.interior_mean_step_m}}},
              {"dsm", dsm},
              {"scene", merged.scene_path},
              {"peak_tile_rss_mb", PeakChildRssMb()},
              {"seconds", total.Seconds()}};
  WriteFileAtomic((city_dir / "run_report.json").string(), summary->dump(2) + "\n");
  spdlog::info("[{}] done in {:.0f} s -> {}", plan.city, total.Seconds(), city_dir.string());
  return true;
}

int RunAll(const RunArgs& args) {
  Stopwatch clock;
  IngestOptions ingest;
  ingest.aois = args.aois;
  ConsoleProgress progress;
  const IngestResult ingested = RunIngest(ingest, args.root, (fs::path(args.out) / "catalogs").string(), progress);
  std::vector<AoiCatalog> catalogs;
  for (const auto& a : ingested.aois) {
    if (a.report.status == StageStatus::kOk) {
      catalogs.push_back(a.catalog);
    } else {
      spdlog::error("{}: ingest failed: {}", a.aoi, a.report.message);
    }
  }
  if (catalogs.empty()) throw Error("run", args.root, "no AOI could be ingested");
  const auto cities = GroupCities(catalogs);
  spdlog::info("run: {} AOI(s) in {} cit{} ({:.1f} s ingest)", catalogs.size(), cities.size(),
               cities.size() == 1 ? "y" : "ies", clock.Seconds());
  int done = 0;
  json summary = json::array();
  for (std::size_t k = 0; k < cities.size(); ++k) {
    spdlog::info("run: city {}/{}", k + 1, cities.size());
    json city;
    try {
      done += RunCity(args, cities[k], &city);
    } catch (const Error& e) {
      spdlog::error("run: {}", e.what());  // one bad city never sinks the batch
      city = {{"error", e.what()}};
    }
    summary.push_back(city);
  }
  WriteFileAtomic((fs::path(args.out) / "run_summary.json").string(),
                  json{{"root", args.root}, {"cities", summary}, {"seconds", clock.Seconds()}}.dump(2) + "\n");
  spdlog::info("run: {} of {} cities reconstructed in {:.0f} s", done, cities.size(), clock.Seconds());
  return done > 0 ? 0 : 1;
}

}  // namespace

void AddRunCommand(CLI::App& app, Runner* runner) {
  auto a = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand(
      "run", "The whole pipeline for every AOI of a DFC2019 tree: ingest, tile, per-tile SfM + splat training, merge "
             "with LOD, DSM export and comparison with the truth; resumable");
  cmd->add_option("root", a->root, "DFC2019 root folder")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", a->out, "Output folder: OUT/<city>/{tiles,scene,run_report.json}, OUT/<AOI>/dsm*")->required();
  cmd->add_option("--aoi", a->aois, "Only these AOIs (repeatable)");
  cmd->add_option("--tile-m", a->tiling.tile_m, "Tile core side [m]")->capture_default_str();
  cmd->add_option("--overlap-m", a->tiling.overlap_m, "Overlap margin [m]")->capture_default_str();
  cmd->add_option("--jobs", a->jobs, "Tiles run at once (0 = bounded by cores and memory)")->capture_default_str();
  AddRunTileOptionsTo(cmd, &a->tile);
  cmd->callback([runner, a] { *runner = [a] { return RunAll(*a); }; });
}

}  // namespace skyfall::cli
