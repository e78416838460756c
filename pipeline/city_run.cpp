#include "pipeline/city_run.h"

#include <fmt/format.h>
#include <sys/resource.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>

#include "core/atomic_file.h"
#include "core/crash_point.h"
#include "core/error.h"
#include "core/ground_cell.h"
#include "products/dsm.h"
#include "products/dsm_report.h"
#include "pipeline/aoi_products.h"
#include "pipeline/city_entries.h"
#include "products/city_report.h"
#include "pipeline/exit_codes.h"
#include "pipeline/inputs_stamp.h"
#include "pipeline/merge_tiles.h"
#include "pipeline/output_lock.h"
#include "products/report_page.h"
#include "pipeline/slurm.h"
#include "products/stac.h"
#include "pipeline/stage_jobs.h"
#include "pipeline/tile_report.h"
#include "pipeline/tile_run.h"
#include "catalogs/aoi_catalog.h"
#include "catalogs/tile_catalog.h"
#include "splat/ply.h"
#include "ingest/dfc2019.h"
#include "ingest/geo.h"
#include "tiling/tiling.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

double PeakChildRssMb() {
  rusage usage{};
  getrusage(RUSAGE_CHILDREN, &usage);
  return usage.ru_maxrss / 1024.0;
}

// Per tile: how it ended, its times and memory, its stages and decisions;
// `reused` when its report predates this run of the city (`run_started`, when
// city_job.json was written): the tile was finished by an earlier run, and
// `seconds` is only this run's check of it.
json TileEntry(const TileOutcome& o, const std::optional<fs::file_time_type>& run_started) {
  json entry = {{"tile", fs::path(o.dir).filename().string()}, {"exit_code", o.exit_code}, {"seconds", o.seconds}};
  const std::optional<TileReport> report = ReadTileReport(o.dir);
  if (!report) {
    entry["status"] = "failed";
    entry["message"] = o.message;
    return entry;
  }
  entry["status"] = ToString(report->status);
  entry["message"] = report->message;
  entry["tile_seconds"] = report->seconds;
  std::error_code ec;
  const fs::file_time_type written = fs::last_write_time(TileReportPath(o.dir), ec);
  entry["reused"] = !ec && run_started && written < *run_started;
  entry["peak_rss_mb"] = report->PeakRssMb();
  entry["stages"] = StageReportsJson(report->stages);
  entry["decisions"] = report->decisions;
  return entry;
}

// True when the city's last run finished with these very inputs and
// options and its products are all there; then `outcome` gets its figures.
bool UnchangedSinceLastRun(const ProductOptions& options, const json& inputs, const std::vector<AoiCatalog>& aois,
                           const std::string& out_dir, CityOutcome* outcome) {
  // No report, or an unreadable one: run the city again.
  const std::optional<CityReport> report = ReadCityReport(outcome->report_path);
  std::error_code unreadable;
  if (!report || !report->scene || report->inputs != inputs || !fs::exists(*report->scene, unreadable)) return false;
  if (report->AnyTileFailed()) return false;  // retry failed tiles
  std::vector<double> mae;
  for (const AoiCatalog& a : aois) {
    for (const std::string& file : AoiProductFiles(options, a, out_dir))
      if (!fs::exists(file, unreadable)) return false;  // a product that cannot be looked at counts as missing
    if (!a.truth) continue;
    const std::optional<double> m = report->DsmMaeM(a.aoi);
    if (!m) return false;
    mae.push_back(*m);
  }
  outcome->dsm_mae_m = mae;
  return true;
}

// Redoes the tiles whose images changed; returns how many.
int ResetChangedTiles(const std::vector<std::string>& tile_dirs, const std::map<std::string, json>& image_stamps,
                      const std::string& city, Progress& progress) {
  int reset = 0;
  for (const std::string& dir : tile_dirs) {
    if (!ResetTileIfInputsChanged(dir, TileInputsStamp(dir, image_stamps))) continue;
    ++reset;
    const std::string tile = fs::path(dir).filename().string();
    progress.Info("[" + city + "] " + tile + ": its images changed since the last run; redoing it");
    Emit(progress, "info", "tiles", city, tile, "images changed since the last run; tile redone");
  }
  return reset;
}

void EmitTileEvents(const std::string& city, const json& tile_list, Progress& progress) {
  for (const json& t : tile_list) {
    const std::string status = t.value("status", "failed");
    std::map<std::string, double> figures = {{"seconds", t.value("seconds", 0.0)},
                                             {"exit_code", t.value("exit_code", 0)}};
    if (t.contains("peak_rss_mb")) figures["peak_rss_mb"] = t.at("peak_rss_mb").get<double>();
    Emit(progress, status == "failed" ? "error" : "info", "tile", city, t.value("tile", ""),
         "tile " + status + (t.value("message", "").empty() ? "" : ": " + t.value("message", "")), figures);
  }
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

namespace {

// What the tile half of a city's run hands to its finishing half (in this
// process, or in the Slurm finish job through OUT/<city>/city_job.json).
struct CityWork {
  std::string city;
  std::string out_dir;
  fs::path city_dir;
  std::vector<std::string> tile_dirs;
  json inputs;
  json stages = json::array();
  int tiles_reset = 0;
};

json CityWorkJson(const CityWork& work, const std::vector<AoiCatalog>& aois) {
  json catalogs = json::array();
  for (const AoiCatalog& a : aois) catalogs.push_back(json::parse(AoiCatalogToJson(a)));
  return {{"schema", "skyfall.city_job/1"}, {"city", work.city},         {"out_dir", work.out_dir},
          {"aois", catalogs},              {"tile_dirs", work.tile_dirs}, {"inputs", work.inputs},
          {"stages", work.stages},         {"tiles_reset", work.tiles_reset}};
}

// A city none of whose tiles produced a scene has nothing to merge: say why
// its tiles did not (one image, no overlap...), not merely that the merge is
// empty. Tiles are judged by their reports (a skipped tile exits 0).
void ThrowIfNoTileFinished(const std::string& city, const std::vector<TileOutcome>& outcomes) {
  std::map<std::string, int> by_status;
  std::string first_reason;
  for (const TileOutcome& o : outcomes) {
    std::string status = o.exit_code == kExitOk ? "ok" : "failed", reason = o.message;
    if (const std::optional<TileReport> report = ReadTileReport(o.dir)) {  // else the exit code and log tail stand
      status = ToString(report->status);
      reason = report->message;
    }
    if (status == "ok") return;
    ++by_status[status];
    if (first_reason.empty()) first_reason = reason;
  }
  if (outcomes.empty()) return;
  std::string counts;
  for (const auto& [status, n] : by_status) counts += (counts.empty() ? "" : ", ") + std::to_string(n) + " " + status;
  throw Error("city", city, fmt::format("no tile produced a scene ({} of {}); first: {}", counts, outcomes.size(),
                                        first_reason));
}

// The city's 3D Tiles; an export that fails does not undo the city.
void ExportCityTiles3d(const RunOptions& options, const CityWork& work, json* stages, CityReport* report,
                       Progress& progress) {
  Stopwatch clock;
  try {
    const Tiles3dSummary t = Export3dTiles((work.city_dir / "scene").string(), (work.city_dir / "3dtiles").string(),
                                           options.exports.tiles3d_options, progress);
    stages->push_back(StageEntry("3dtiles", "ok", clock.Seconds()));
    report->tiles3d = json{{"tileset", t.tileset_path}, {"tiles", t.tiles}, {"contents", t.contents},
                           {"gaussians", t.gaussians}};
  } catch (const Error& e) {
    progress.Warn("[" + work.city + "] 3D Tiles export: " + e.what());
    stages->push_back(StageEntry("3dtiles", "failed", clock.Seconds(), e.what()));
  }
}

// What the merge decided (LOD levels, the DSMs' surface) and why.
json MergeDecisions(const RunOptions& options, const MergeSummary& merged) {
  json decisions = {{"lod_levels", {{"levels", merged.lod_levels},
                                    {"why", fmt::format("a coarser level is kept when it has at most {:.0f}% of the "
                                                        "previous level's Gaussians; the pyramid ends at the first "
                                                        "level of at most {} Gaussians (or after {} levels)",
                                                        100 * options.merge.lod.min_reduction,
                                                        options.merge.lod.min_gaussians,
                                                        options.merge.lod.max_levels)}}}};
  decisions["dsm_source"] = {
      {"source", merged.surface_source},
      {"surface", merged.surface_path},
      {"why", merged.surface_source == "reconstruction"
                  ? "dsm.source is reconstruction: the DSMs come from the tiles' scenes trained on the real images; "
                    "the synthesis stage's scene (scene.ply, the LOD) also trained on the refiner's orbit renders"
              : options.dsm.source == DsmSource::kFinal ? "dsm.source is final: the DSMs come from the merged scene"
                                                        : "no synthesis stage ran: the reconstruction is the merged scene"}};
  return decisions;
}

// Merge with LOD, DSM export and comparison, run report (last) and STAC
// catalog of a city whose tiles have run.
CityOutcome FinishCity(const RunOptions& options, const std::vector<AoiCatalog>& aois, const CityWork& work,
                       const std::vector<TileOutcome>& outcomes, const Stopwatch& total, Progress& progress) {
  CityOutcome outcome;
  outcome.city = work.city;
  outcome.report_path = CityReportPath(work.city_dir).string();
  outcome.tiles_reset = work.tiles_reset;
  json stages = work.stages;
  json tile_list = json::array();
  int failed = 0;
  std::error_code ec;
  const fs::file_time_type job_written = fs::last_write_time(work.city_dir / "city_job.json", ec);
  const std::optional<fs::file_time_type> run_started = ec ? std::nullopt : std::optional(job_written);
  for (const TileOutcome& o : outcomes) {
    failed += o.exit_code != kExitOk && o.exit_code != kExitDegenerate;
    tile_list.push_back(TileEntry(o, run_started));
  }
  outcome.tiles_failed = failed;
  EmitTileEvents(work.city, tile_list, progress);
  CityReport report;
  report.city = work.city;
  report.options = json::parse(RunOptionsToJson(options));
  report.tiles = tile_list;
  for (const auto& a : aois) report.aois.push_back(a.aoi);

  Stopwatch clock;
  MergeSummary merged;
  CrashPoint("merge");
  try {
    ThrowIfNoTileFinished(work.city, outcomes);
    merged = MergeTiles((work.city_dir / "tiles").string(), (work.city_dir / "scene").string(), options.merge,
                        options.dsm, progress);
    stages.push_back(StageEntry("merge", "ok", clock.Seconds()));
  } catch (const Error& e) {
    progress.Warn("[" + work.city + "] merge: " + e.what());
    Emit(progress, "error", "merge", work.city, "", e.what());
    stages.push_back(StageEntry("merge", "failed", clock.Seconds(), e.what()));
    outcome.error = e.what();
    report.stages = stages;
    report.seconds = total.Seconds();
    WriteCityReport(outcome.report_path, report);
    return outcome;
  }
  outcome.scene = true;
  CrashPoint("dsm");
  const AoiProducts products =
      WriteAoiProducts(options, aois, merged, work.tile_dirs, work.out_dir, &stages, &outcome, progress);
  report.dsm = products.comparisons;
  report.products = products.products;
  report.city_products = products.city;
  if (options.exports.tiles3d) ExportCityTiles3d(options, work, &stages, &report, progress);
  report.stages = stages;
  report.merge = merged.report.metrics;
  report.decisions = MergeDecisions(options, merged);
  // How the tiles' bundle adjustments share one frame (the tiling's choice).
  const json index = ReadRecordOrNull((work.city_dir / "tiles" / "tiles.json").string());
  if (index.contains("gauge")) report.decisions["absolute_position"] = {{"tiles", index["gauge"]}};
  report.seam = {{"ratio", FiniteOrNull(merged.seam.ratio)},
                 {"boundary_mean_step_m", FiniteOrNull(merged.seam.boundary_mean_step_m)},
                 {"interior_mean_step_m", FiniteOrNull(merged.seam.interior_mean_step_m)}};
  report.scene = merged.scene_path;
  report.peak_tile_rss_mb = PeakChildRssMb();
  report.seconds = total.Seconds();
  report.inputs = work.inputs;  // what the next run compares to skip an unchanged city
  CrashPoint("report");
  WriteCityReport(outcome.report_path, report);
  CrashPoint("stac");
  WriteCityStac({work.city, work.out_dir, aois, work.tile_dirs, (work.city_dir / "scene").string(),
                 outcome.report_path, UtcNowIso()});
  Emit(progress, "info", "city", work.city, "", "done",
       {{"seconds", total.Seconds()}, {"tiles_failed", static_cast<double>(failed)},
        {"tiles_reset", static_cast<double>(work.tiles_reset)}, {"peak_tile_rss_mb", PeakChildRssMb()}});
  progress.Info(fmt::format("[{}] done in {:.0f} s -> {}", work.city, total.Seconds(), work.city_dir.string()));
  return outcome;
}

// The Slurm path of a city: submit (or find still queued) the tile array and
// the finish job, wait for the finish job, and read back what it wrote.
CityOutcome RunCityOnSlurm(const RunOptions& options, const CityWork& work, const std::string& config_path,
                           Progress& progress) {
  CityOutcome outcome;
  outcome.city = work.city;
  outcome.report_path = CityReportPath(work.city_dir).string();
  outcome.tiles_reset = work.tiles_reset;
  SlurmCityJobs jobs;
  if (ReadSlurmJobs(work.city_dir.string(), &jobs) && !SlurmJobState(jobs.finish_job).empty()) {
    progress.Info(fmt::format("[{}] Slurm job {} of an earlier run is still queued: waiting for it", work.city,
                              jobs.finish_job));
  } else {
    std::vector<std::string> unfinished;
    for (const std::string& dir : work.tile_dirs) {
      if (!TileFinished(dir, options)) unfinished.push_back(dir);
    }
    jobs = SubmitSlurmCity(options, work.city_dir.string(), unfinished, config_path);
    progress.Info(fmt::format("[{}] submitted {} of {} tile(s) as Slurm array job {}, merge and DSM as job {} "
                              "(scripts under {})",
                              work.city, unfinished.size(), work.tile_dirs.size(),
                              jobs.tiles_job.empty() ? "-" : jobs.tiles_job, jobs.finish_job,
                              (work.city_dir / "slurm").string()));
    Emit(progress, "info", "slurm", work.city, "", "submitted",
         {{"tiles", static_cast<double>(unfinished.size())},
          {"tiles_job", jobs.tiles_job.empty() ? -1.0 : std::stod(jobs.tiles_job)},
          {"finish_job", std::stod(jobs.finish_job)}});
  }
  progress.Begin("tiles on Slurm", jobs.tiles.size());
  std::size_t reported = 0;
  const std::string end = WaitForSlurmJob(jobs.finish_job, jobs.tiles_job, options.executor.slurm.poll_s, [&] {
    std::size_t finished = 0;
    for (const std::string& t : jobs.tiles) finished += fs::exists(fs::path(t) / "tile_report.json");
    if (finished != reported) progress.Advance(reported = finished, "");
  });
  progress.End();
  for (const std::string& dir : work.tile_dirs) {
    const TileOutcome o = TileOutcomeFromReport(dir);
    outcome.tiles_failed += o.exit_code != kExitOk && o.exit_code != kExitDegenerate;
  }
  const std::string finish_log = (work.city_dir / "slurm" / ("finish_" + jobs.finish_job + ".out")).string();
  if (end.rfind("held:", 0) == 0) {
    outcome.error = fmt::format("Slurm {}; the jobs were cancelled; see {}/slurm/ and the cluster's slurmd log, "
                                "then rerun", end, work.city_dir.string());
    progress.Warn("[" + work.city + "] " + outcome.error);
    Emit(progress, "error", "slurm", work.city, "", outcome.error);
    return outcome;
  }
  if (end == "dependency_never_satisfied") {
    outcome.error = fmt::format("{} tile job(s) failed, so the merge job {} was cancelled; see the tiles' run.log "
                                "and {}/slurm/tile_*.out; a rerun resubmits the unfinished tiles",
                                std::max(outcome.tiles_failed, 1), jobs.finish_job, work.city_dir.string());
    progress.Warn("[" + work.city + "] " + outcome.error);
    Emit(progress, "error", "slurm", work.city, "", outcome.error);
    return outcome;
  }
  const std::optional<CityReport> report = ReadCityReport(outcome.report_path);
  const std::optional<std::vector<double>> mae = report ? report->DsmMaesM() : std::nullopt;
  if (report && report->scene && report->inputs == work.inputs && mae) {
    outcome.scene = true;
    outcome.dsm_mae_m = *mae;
    return outcome;
  }
  outcome.error = "the Slurm finish job " + jobs.finish_job + " ended without a run report; see " + finish_log;
  progress.Warn("[" + work.city + "] " + outcome.error);
  Emit(progress, "error", "slurm", work.city, "", outcome.error);
  return outcome;
}

// How a city's written tiles are run and the city finished
// (ExecutorOptions::kind): here (as local processes or in this process),
// then merged here; or on Slurm, as a job array whose dependent job merges.
class CityExecutor {
 public:
  virtual ~CityExecutor() = default;
  virtual CityOutcome Run(const RunOptions& options, const std::vector<AoiCatalog>& aois, CityWork& work,
                          const std::string& config_path, const Stopwatch& total, Progress& progress) const = 0;
};

class HereCityExecutor final : public CityExecutor {
 public:
  CityOutcome Run(const RunOptions& options, const std::vector<AoiCatalog>& aois, CityWork& work,
                  const std::string& config_path, const Stopwatch& total, Progress& progress) const override {
    Stopwatch clock;
    const std::vector<TileOutcome> outcomes = RunTiles(work.tile_dirs, options, config_path, progress);
    int failed = 0;
    for (const TileOutcome& o : outcomes) failed += o.exit_code != kExitOk && o.exit_code != kExitDegenerate;
    work.stages.push_back(StageEntry("tiles", failed ? "partial" : "ok", clock.Seconds(),
                                     failed ? std::to_string(failed) + " tile(s) failed" : ""));
    return FinishCity(options, aois, work, outcomes, total, progress);
  }
};

class SlurmCityExecutor final : public CityExecutor {
 public:
  CityOutcome Run(const RunOptions& options, const std::vector<AoiCatalog>& /*aois*/, CityWork& work,
                  const std::string& config_path, const Stopwatch& /*total*/, Progress& progress) const override {
    return RunCityOnSlurm(options, work, config_path, progress);
  }
};

std::unique_ptr<CityExecutor> MakeCityExecutor(ExecutorKind kind) {
  if (kind == ExecutorKind::kSlurm) return std::make_unique<SlurmCityExecutor>();
  return std::make_unique<HereCityExecutor>();  // local processes or inline: RunTiles tells them apart
}

}  // namespace

CityOutcome RunCity(const RunOptions& options, const std::vector<AoiCatalog>& aois, const std::string& out_dir,
                    Progress& progress) {
  options.Check();
  CheckOrthoImage(options.products, aois);  // before hours of tiles, not after
  Stopwatch total, clock;
  const TilePlan plan = PlanTiles(options.tiling, aois);
  CityWork work;
  work.city = plan.city;
  work.out_dir = out_dir;
  work.city_dir = fs::path(out_dir) / plan.city;
  const std::map<std::string, json> image_stamps = ImageStamps(aois);
  work.inputs = CityInputsStamp(options, aois, image_stamps);
  // Tiles holding different passes share a frame through the acquisitions all
  // hold: another such set is another reconstruction (a city made before it
  // existed is redone once). Absent, the stamp is what it always was.
  for (const AoiCatalog& c : plan.catalogs)
    if (!c.gauge_acquisitions.empty()) work.inputs["gauge_acquisitions"] = c.gauge_acquisitions;
  CityOutcome unchanged;
  unchanged.city = plan.city;
  unchanged.report_path = CityReportPath(work.city_dir).string();
  if (UnchangedSinceLastRun(options.products, work.inputs, aois, out_dir, &unchanged)) {
    unchanged.scene = true;
    unchanged.unchanged = true;
    progress.Info("[" + plan.city + "] inputs and options unchanged since its last run: nothing to recompute");
    Emit(progress, "info", "city", plan.city, "", "unchanged since the last run; nothing recomputed");
    return unchanged;
  }
  progress.Info(fmt::format("[{}] {} AOI(s), {}x{} tiles of {} m ({}; finest image GSD {:.2f} m, {:.0f} px and {:.0f} dense cells a tile)",
                            plan.city, aois.size(), plan.grid.cols, plan.grid.rows, plan.grid.tile_m,
                            plan.tile_side_automatic ? "sized by the imagery" : "as given",
                            plan.finest_gsd_m, plan.finest_gsd_m > 0 ? plan.grid.tile_m / plan.finest_gsd_m : 0.0,
                            plan.grid.tile_m / DenseCellForGsdM(plan.finest_gsd_m)));
  const std::string frame_line = "[" + plan.city + "] frame of the tiles' bundle adjustments: " + plan.gauge;
  if (plan.gauge_shared) progress.Info(frame_line);
  else progress.Warn(frame_line);
  Emit(progress, "info", "city", plan.city, "", "start",
       {{"aois", static_cast<double>(aois.size())}, {"tiles", static_cast<double>(plan.grid.cols * plan.grid.rows)}});
  const TilingResult tiles = WriteTiles(plan, (work.city_dir / "tiles").string(), progress);
  work.tile_dirs = tiles.tile_dirs;
  work.tiles_reset = ResetChangedTiles(tiles.tile_dirs, image_stamps, plan.city, progress);
  work.stages.push_back(StageEntry("tile", "ok", clock.Seconds()));
  // The tiles' processes read the options from this file; it is also the
  // record of what this city was run with.
  const std::string config_path = (work.city_dir / "run_config.json").string();
  WriteFileIfChanged(config_path, RunOptionsToJson(options));
  WriteFileAtomic((work.city_dir / "city_job.json").string(), CityWorkJson(work, aois).dump(2) + "\n");
  return MakeCityExecutor(options.executor.kind)->Run(options, aois, work, config_path, total, progress);
}

CityOutcome FinishCityFromFiles(const std::string& city_dir, Progress& progress) {
  Stopwatch total;
  const fs::path dir(city_dir);
  const std::string job_path = (dir / "city_job.json").string();
  const std::string config_path = (dir / "run_config.json").string();
  const RunOptions options = RunOptionsFromJson(ReadTextFile(config_path), config_path);
  json job;
  try {
    job = json::parse(ReadTextFile(job_path));
  } catch (const json::exception& e) {
    throw Error("finish-city", job_path, std::string("not valid JSON: ") + e.what());
  }
  if (job.value("schema", "") != "skyfall.city_job/1") {
    throw Error("finish-city", job_path, "schema is not skyfall.city_job/1");
  }
  CityWork work;
  std::vector<AoiCatalog> aois;
  try {
    work.city = job.at("city");
    work.out_dir = job.at("out_dir");
    work.city_dir = dir;
    work.tile_dirs = job.at("tile_dirs").get<std::vector<std::string>>();
    work.inputs = job.at("inputs");
    work.stages = job.at("stages");
    work.tiles_reset = job.value("tiles_reset", 0);
    for (const json& a : job.at("aois")) aois.push_back(AoiCatalogFromJson(a.dump(), job_path));
  } catch (const json::exception& e) {
    throw Error("finish-city", job_path, std::string("missing or bad field: ") + e.what());
  }
  std::vector<TileOutcome> outcomes;
  for (const std::string& t : work.tile_dirs) outcomes.push_back(TileOutcomeFromReport(t));
  return FinishCity(options, aois, work, outcomes, total, progress);
}

namespace {

// Ingests the request's AOIs into OUT/catalogs: the catalogs that can run,
// and every AOI found with what was left out of it and why.
json IngestAois(const RunOptions& options, const RunRequest& request, Progress& progress,
                std::vector<AoiCatalog>* catalogs, RunSummary* summary) {
  IngestOptions ingest = options.ingest;
  ingest.aois = request.aois;
  const IngestResult ingested = RunIngest(ingest, request.root, (fs::path(request.out) / "catalogs").string(), progress);
  json aoi_list = json::array();
  for (const auto& a : ingested.aois) {
    json skipped = json::array();
    for (const Skipped& s : a.skipped_images) skipped.push_back({{"file", s.what}, {"reason", s.reason}});
    aoi_list.push_back({{"aoi", a.aoi},
                        {"ingest", a.report.status == StageStatus::kOk ? "ok" : "failed"},
                        {"error", a.report.status == StageStatus::kOk ? "" : a.report.message},
                        {"images", a.catalog.images.size()},
                        {"skipped_images", skipped}});
    if (a.report.status == StageStatus::kOk) {
      catalogs->push_back(a.catalog);
      Emit(progress, "info", "ingest", a.aoi, "", "ingested", {{"images", static_cast<double>(a.catalog.images.size())}});
    } else {
      progress.Warn(a.aoi + ": ingest failed: " + a.report.message);
      Emit(progress, "error", "ingest", a.aoi, "", a.report.message);
      ++summary->aois_failed;
    }
  }
  summary->aois_ingested = static_cast<int>(catalogs->size());
  return aoi_list;
}

}  // namespace

RunSummary RunAll(const RunOptions& options, const RunRequest& request, Progress& progress) {
  options.Check();
  if (request.root.empty()) throw Error("run", "root", "no input folder given");
  if (request.out.empty()) throw Error("run", "out", "no output folder given");
  Stopwatch clock;
  RunSummary summary;
  LockHolder holder;
  const std::optional<OutputLock> lock = OutputLock::Acquire(request.out, request.wait_lock_s, &holder);
  if (!lock) {
    summary.exit_code = kExitLocked;
    summary.lock_holder = DescribeHolder(holder);
    Emit(progress, "error", "run", "", "", request.out + " is locked: " + summary.lock_holder);
    return summary;
  }
  Emit(progress, "info", "run", "", "", "start: " + request.root + " -> " + request.out);
  std::vector<AoiCatalog> catalogs;
  const json aoi_list = IngestAois(options, request, progress, &catalogs, &summary);
  if (catalogs.empty()) throw Error("run", request.root, "no AOI could be ingested");
  const auto cities = GroupCities(catalogs);
  progress.Info(fmt::format("run: {} AOI(s) in {} cit{} ({:.1f} s ingest)", catalogs.size(), cities.size(),
                            cities.size() == 1 ? "y" : "ies", clock.Seconds()));
  json list = json::array();
  int done = 0, unchanged = 0, incomplete = 0;
  for (std::size_t k = 0; k < cities.size(); ++k) {
    progress.Info(fmt::format("run: city {}/{}", k + 1, cities.size()));
    CityOutcome city;
    try {
      city = RunCity(options, cities[k], request.out, progress);
    } catch (const Error& e) {
      progress.Warn(std::string("run: ") + e.what());  // one bad city never sinks the batch
      Emit(progress, "error", "city", cities[k].front().aoi, "", e.what());
      city.city = cities[k].front().aoi;
      city.error = e.what();
    }
    done += city.scene;
    unchanged += city.unchanged;
    incomplete += !city.scene || city.tiles_failed > 0;
    list.push_back({{"city", city.city}, {"scene", city.scene}, {"unchanged", city.unchanged},
                    {"tiles_failed", city.tiles_failed}, {"tiles_reset", city.tiles_reset},
                    {"report", city.report_path}, {"error", city.error}});
    summary.cities.push_back(std::move(city));
  }
  summary.seconds = clock.Seconds();
  summary.exit_code = done == 0 ? kExitNothingDone : (incomplete > 0 || summary.aois_failed > 0) ? kExitPartial : kExitOk;
  WriteRootStacCatalog(request.out);
  CrashPoint("summary");
  WriteFileAtomic((fs::path(request.out) / "run_summary.json").string(),
                  json{{"root", request.root}, {"aois", aoi_list}, {"cities", list}, {"aois_failed", summary.aois_failed},
                       {"exit_code", summary.exit_code}, {"seconds", summary.seconds}}
                          .dump(2) + "\n");
  try {
    progress.Info("run: report page " + WriteRunReportPage(request.out));
  } catch (const Error& e) {  // the page is for people; the products stand without it
    progress.Warn(std::string("run: report page: ") + e.what());
  }
  progress.Info(fmt::format("run: {} of {} cities reconstructed ({} unchanged since the last run) in {:.0f} s", done,
                            cities.size(), unchanged, summary.seconds));
  Emit(progress, summary.exit_code == kExitOk ? "info" : "warning", "run", "", "", "end",
       {{"cities", static_cast<double>(cities.size())}, {"cities_done", static_cast<double>(done)},
        {"cities_unchanged", static_cast<double>(unchanged)}, {"aois_failed", static_cast<double>(summary.aois_failed)},
        {"exit_code", static_cast<double>(summary.exit_code)}, {"seconds", summary.seconds}});
  return summary;
}

}  // namespace skyfall
