#include "apps/tile_jobs.h"

#include <spawn.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <tbb/global_control.h>
#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "apps/commands.h"
#include "apps/jobs.h"
#include "core/format.h"
#include "catalogs/aoi_catalog.h"
#include "catalogs/tile_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "merge/dsm.h"
#include "splat/ply.h"

extern char** environ;

namespace skyfall::cli {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

json OptionsJson(const TileRunOptions& o) {
  return {{"iterations", o.iterations}, {"resolution_downscale", o.downscale}, {"depth_prior", o.depth_prior},
          {"appearance", o.appearance},
          {"init_max_scale_m", o.init_max_scale_m}, {"init_pieces", o.init_pieces}, {"init_points", o.init_points}};
}

json StageJson(const StageReport& r) {
  return {{"stage", r.stage}, {"status", ToString(r.status)}, {"message", r.message}, {"seconds", r.seconds},
          {"metrics", r.metrics}, {"warnings", r.warnings}};
}

StageReport WriteTileReport(const std::string& dir, const TileSpec& spec, const TileRunOptions& o, StageReport report,
                            const std::vector<StageReport>& stages) {
  json list = json::array();
  for (const StageReport& s : stages) list.push_back(StageJson(s));
  report.stage = "run-tile";
  report.metrics["peak_rss_mb"] = PeakRssMb();
  const json doc = {{"tile", spec.id}, {"status", ToString(report.status)}, {"message", report.message},
                    {"options", OptionsJson(o)}, {"images", spec.images.size()},
                    {"seconds", report.seconds}, {"metrics", report.metrics}, {"stages", list}};
  WriteFileAtomic((fs::path(dir) / "tile_report.json").string(), doc.dump(2) + "\n");
  return report;
}

// A finished run with the same options, if there is one.
bool AlreadyDone(const std::string& dir, const TileRunOptions& o, StageReport* report) {
  const fs::path path = fs::path(dir) / "tile_report.json";
  if (!fs::exists(path)) return false;
  try {
    const json doc = json::parse(ReadTextFile(path.string()));
    if (doc.at("options") != OptionsJson(o)) return false;
    const std::string status = doc.at("status").get<std::string>();
    if (status == "ok" && !fs::exists(fs::path(dir) / "splat" / "scene.ply")) return false;
    report->status = status == "ok" ? StageStatus::kOk : status == "degenerate" ? StageStatus::kDegenerate
                                                                                : StageStatus::kSkipped;
    report->message = "already done (" + status + ")";
    return status == "ok" || status == "degenerate" || status == "skipped";
  } catch (const std::exception&) {
    return false;  // unreadable report: redo the tile
  }
}

bool SfmDone(const fs::path& sfm_dir) {
  try {
    const json doc = json::parse(ReadTextFile((sfm_dir / "sfm_report.json").string()));
    return doc.value("status", "") == "ok" && fs::exists(sfm_dir / "points.ply") && fs::exists(sfm_dir / "cameras.json");
  } catch (const std::exception&) {
    return false;
  }
}

StageReport ReusedStage(const std::string& stage, const std::string& what) {
  StageReport reused;
  reused.stage = stage;
  reused.status = StageStatus::kSkipped;
  reused.message = "reused " + what + " of an earlier run";
  return reused;
}

}  // namespace

StageReport RunTile(const std::string& tile_dir, const TileRunOptions& options, Progress& progress) {
  Stopwatch clock;
  const TileSpec spec = ReadTileSpec((fs::path(tile_dir) / "tile.json").string());
  StageReport report;
  report.stage = "run-tile";
  if (AlreadyDone(tile_dir, options, &report)) return report;
  std::unique_ptr<tbb::global_control> threads;
  if (options.threads > 0) {
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, options.threads);
  }
  if (spec.images.empty()) {
    report.status = StageStatus::kSkipped;
    report.message = spec.id + ": fewer than 2 images see this tile; nothing to reconstruct";
    return WriteTileReport(tile_dir, spec, options, report, {});
  }
  std::vector<StageReport> stages;
  const fs::path sfm_dir = fs::path(tile_dir) / "sfm";
  if (SfmDone(sfm_dir)) {
    stages.push_back(ReusedStage("sfm", "the finished SfM"));
  } else {
    const AoiCatalog catalog = ReadAoiCatalog((fs::path(tile_dir) / "aoi.json").string());
    const SfmResult sfm = RunSfmJob(SfmOptions{}, catalog, sfm_dir.string(), false, progress);
    stages.push_back(sfm.report);
    if (sfm.report.status != StageStatus::kOk) {
      report.status = StageStatus::kDegenerate;
      report.message = spec.id + ": " + sfm.report.message;
      report.seconds = clock.Seconds();
      return WriteTileReport(tile_dir, spec, options, report, stages);
    }
  }
  if (options.init_points != "sparse") {
    if (DenseDone(sfm_dir.string(), DenseOptions{}, spec.extent)) {
      stages.push_back(ReusedStage("dense", "the finished dense heights"));
    } else {
      const DenseResult dense = RunDenseJob(DenseOptions{}, sfm_dir.string(), progress, spec.extent);
      stages.push_back(dense.report);
      if (dense.report.status != StageStatus::kOk) progress.Warn(spec.id + ": " + dense.report.message);
    }
  }
  TrainJob job;
  job.sfm_dir = sfm_dir.string();
  job.out_dir = (fs::path(tile_dir) / "splat").string();
  job.options.iterations = options.iterations;
  job.options.pseudo_interval = 4;
  job.downscale = options.downscale;
  job.depth_prior = options.depth_prior;
  job.appearance = options.appearance;
  job.init_max_scale_m = options.init_max_scale_m;
  job.init_pieces = options.init_pieces;
  job.init_points = options.init_points;
  const TrainResult train = RunTrainJob(job, progress);
  StageReport splat = train.report;
  splat.stage = "splat";
  splat.metrics["gaussians"] = static_cast<double>(train.cloud.size());
  if (!train.series.empty()) splat.metrics["psnr_test_db"] = train.series.back().psnr_test_db;
  stages.push_back(splat);
  report.seconds = clock.Seconds();
  report.metrics["gaussians"] = static_cast<double>(train.cloud.size());
  return WriteTileReport(tile_dir, spec, options, report, stages);
}

int TileExitCode(const StageReport& report) {
  return report.status == StageStatus::kDegenerate ? kExitDegenerate : report.status == StageStatus::kFailed ? 1 : 0;
}

namespace {

// [MB] memory a tile run needs: a base (code, TBB, SfM tracks) plus per
// full-resolution crop pixel (SIFT pyramids and float training images);
// measured peaks: JAX_068 (19 crops, 12 Mpx) 280 MB SfM, 250 MB training.
constexpr double kTileBaseMb = 300.0;
constexpr double kTileBytesPerPixel = 40.0;

double AvailableMemoryMb() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  double kb = 0;
  std::string unit;
  while (in >> key >> kb >> unit) {
    if (key == "MemAvailable:") return kb / 1024.0;
  }
  return 4096.0;  // unknown: assume a small machine
}

double TileMemoryMb(const std::string& dir) {
  double pixels = 0;
  try {
    for (const TileImage& im : ReadTileSpec((fs::path(dir) / "tile.json").string()).images) {
      pixels += static_cast<double>(im.width_px) * im.height_px;
    }
  } catch (const Error&) {
  }
  return kTileBaseMb + kTileBytesPerPixel * pixels / 1e6;
}

std::string TailOf(const fs::path& log, std::size_t max_chars = 600) {
  std::string text;
  try {
    text = ReadTextFile(log.string());
  } catch (const Error&) {
    return "";
  }
  return text.size() > max_chars ? text.substr(text.size() - max_chars) : text;
}

}  // namespace

int ParallelTileJobs(const std::vector<std::string>& tile_dirs, int requested, std::string* why) {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  double largest_mb = 0;
  for (const auto& d : tile_dirs) largest_mb = std::max(largest_mb, TileMemoryMb(d));
  const double available_mb = AvailableMemoryMb();
  const int by_memory = std::max(1, static_cast<int>(0.8 * available_mb / std::max(largest_mb, 1.0)));
  const int wanted = requested > 0 ? requested : cores;
  const int jobs = std::max(1, std::min({wanted, cores, by_memory, static_cast<int>(tile_dirs.size())}));
  if (why) {
    *why = fmt::format("{} parallel tile(s): {} requested, {} cores, memory for {} ({:.0f} MB available, "
                       "~{:.0f} MB per tile)", jobs, wanted, cores, by_memory, available_mb, largest_mb);
  }
  return jobs;
}

std::vector<TileOutcome> RunTilesInParallel(const std::vector<std::string>& tile_dirs, const TileRunOptions& options,
                                            int jobs, Progress& progress) {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int threads = std::max(1, cores / std::max(1, jobs));
  const std::string self = fs::read_symlink("/proc/self/exe").string();
  std::vector<TileOutcome> outcomes(tile_dirs.size());
  std::map<pid_t, std::pair<std::size_t, std::chrono::steady_clock::time_point>> running;
  std::size_t next = 0, done = 0;
  progress.Begin("tiles", tile_dirs.size());
  auto launch = [&](std::size_t k) {
    outcomes[k].dir = tile_dirs[k];
    std::vector<std::string> args = {self, "-q", "run-tile", tile_dirs[k], "--iterations",
                                     std::to_string(options.iterations), "--resolution", std::to_string(options.downscale),
                                     "--depth-prior", options.depth_prior, "--appearance", options.appearance,
                                     "--init-max-scale", FormatDouble(options.init_max_scale_m),
                                     "--init-pieces", std::to_string(options.init_pieces),
                                     "--init-points", options.init_points,
                                     "--threads", std::to_string(threads)};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const std::string log = (fs::path(tile_dirs[k]) / "run.log").string();
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    pid_t pid = 0;
    const int rc = posix_spawn(&pid, self.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) throw Error("run", tile_dirs[k], std::string("cannot start a tile process: ") + std::strerror(rc));
    running[pid] = {k, std::chrono::steady_clock::now()};
  };
  while (done < tile_dirs.size()) {
    while (next < tile_dirs.size() && static_cast<int>(running.size()) < jobs) launch(next++);
    int status = 0;
    const pid_t pid = waitpid(-1, &status, 0);
    if (pid < 0) {
      if (errno == EINTR) continue;
      throw Error("run", "", std::string("waitpid failed: ") + std::strerror(errno));
    }
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    TileOutcome& o = outcomes[it->second.first];
    o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - it->second.second).count();
    o.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    if (o.exit_code != 0) o.message = TailOf(fs::path(o.dir) / "run.log");
    running.erase(it);
    const std::string name = fs::path(o.dir).filename().string();
    if (o.exit_code == kExitDegenerate) {
      progress.Warn("tile " + name + " is degenerate (too little data); see " + o.dir + "/tile_report.json");
    } else if (o.exit_code != 0) {
      progress.Warn("tile " + name + " failed (exit " + std::to_string(o.exit_code) + "): " + o.message);
    }
    progress.Advance(++done, fmt::format("{} exit {} {:.0f} s", name, o.exit_code, o.seconds));
  }
  progress.End();
  return outcomes;
}

MergeSummary MergeTiles(const std::string& tiles_dir, const std::string& out_dir, const MergeOptions& options,
                        Progress& progress) {
  Stopwatch clock;
  MergeSummary summary;
  summary.report.stage = "merge";
  const fs::path index_path = fs::path(tiles_dir) / "tiles.json";
  json index;
  try {
    index = json::parse(ReadTextFile(index_path.string()));
  } catch (const json::exception& e) {
    throw Error("merge", index_path.string(), std::string("not valid JSON: ") + e.what());
  }
  std::vector<TileCloud> clouds;
  std::vector<std::string> missing;
  const json& tiles = index.at("tiles");
  progress.Begin("merge: reading tiles", tiles.size());
  std::size_t k = 0;
  for (const json& t : tiles) {
    const fs::path dir = fs::path(tiles_dir) / t.at("id").get<std::string>();
    const TileSpec spec = ReadTileSpec((dir / "tile.json").string());
    if (summary.epsg == 0 && fs::exists(dir / "aoi.json")) summary.epsg = ReadAoiCatalog((dir / "aoi.json").string()).epsg;
    const fs::path scene = dir / "splat" / "scene.ply";
    bool ok = false;
    try {
      ok = json::parse(ReadTextFile((dir / "tile_report.json").string())).value("status", "") == "ok" && fs::exists(scene);
    } catch (const std::exception&) {
    }
    if (ok) {
      clouds.push_back({spec, ReadGaussiansPly(scene.string())});
    } else {
      missing.push_back(spec.id);
      progress.Warn("merge: tile " + spec.id + " has no finished scene; its area is left to its neighbours");
    }
    progress.Advance(++k, spec.id);
  }
  progress.End();
  if (clouds.empty()) throw Error("merge", tiles_dir, "no finished tile to merge (run `skyfall run-tile` first)");
  const json& o = index.at("enu_origin");
  summary.enu_origin = {o.at("lon_deg").get<double>(), o.at("lat_deg").get<double>(), o.at("height_m").get<double>()};

  const StitchResult stitched = StitchTiles(options.stitch, summary.enu_origin, clouds);
  fs::create_directories(out_dir);
  summary.scene_path = (fs::path(out_dir) / "scene.ply").string();
  WriteGaussiansPly(summary.scene_path, stitched.cloud);
  const std::vector<LodLevel> lod = BuildLod(options.lod, stitched.cloud);
  WriteLod(out_dir, lod);

  // Seam metric on a city DSM rendered from the merged scene.
  const GroundBox bounds = BoxFromJson(index.at("bounds"));
  DsmGrid city = GridCovering(bounds, summary.enu_origin, summary.epsg, options.seam_gsd_m);
  RasterizeDsm(stitched.cloud, summary.enu_origin, DsmExportOptions{}, &city);
  WriteDsm((fs::path(out_dir) / "dsm_city.tif").string(), city);
  summary.seam = MeasureSeams(city, clouds[0].tile.grid, summary.enu_origin);
  summary.tiles_merged = clouds.size();
  summary.tiles_missing = missing.size();

  json levels = json::array();
  for (const LodLevel& l : lod) {
    levels.push_back({{"level", l.level}, {"count", l.cloud.size()}, {"voxel_m", l.voxel_m},
                      {"geometric_error_m", l.geometric_error_m}});
  }
  auto finite = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  const json frame = {{"enu_origin", o}, {"epsg", summary.epsg}, {"city", index.at("city")}};
  WriteFileAtomic((fs::path(out_dir) / "frame.json").string(), frame.dump(2) + "\n");
  summary.report.seconds = clock.Seconds();
  summary.report.metrics = stitched.report.metrics;
  summary.report.metrics["seam_ratio"] = summary.seam.ratio;
  const json doc = {{"city", index.at("city")},
                    {"tiles_merged", summary.tiles_merged},
                    {"tiles_missing", missing},
                    {"stitch", stitched.report.metrics},
                    {"seam", {{"boundary_mean_step_m", finite(summary.seam.boundary_mean_step_m)},
                              {"interior_mean_step_m", finite(summary.seam.interior_mean_step_m)},
                              {"ratio", finite(summary.seam.ratio)},
                              {"boundary_pairs", summary.seam.boundary_pairs},
                              {"interior_pairs", summary.seam.interior_pairs}}},
                    {"lod", levels},
                    {"seconds", summary.report.seconds}};
  WriteFileAtomic((fs::path(out_dir) / "merge_report.json").string(), doc.dump(2) + "\n");
  return summary;
}

}  // namespace skyfall::cli
