#include "pipeline/tile_run.h"

#include <signal.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <fmt/format.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <tbb/global_control.h>
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "core/crash_point.h"
#include "pipeline/city_entries.h"
#include "pipeline/exit_codes.h"
#include "pipeline/tile_report.h"
#include "pipeline/stage_jobs.h"
#include "core/format.h"
#include "catalogs/aoi_catalog.h"
#include "catalogs/tile_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"

extern char** environ;

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

json OptionsJson(const RunOptions& o) { return json::parse(TileOptionsJson(o)); }

StageReport WriteReport(const std::string& dir, const TileSpec& spec, const RunOptions& o, StageReport report,
                        const std::vector<StageReport>& stages, const json& decisions = json::object()) {
  report.stage = "run-tile";
  report.metrics["peak_rss_mb"] = PeakSelfRssMb();
  TileReport doc;
  doc.tile = spec.id;
  doc.status = report.status;
  doc.message = report.message;
  doc.options = OptionsJson(o);
  doc.decisions = decisions;
  doc.images = spec.images.size();
  doc.seconds = report.seconds;
  doc.metrics = report.metrics;
  doc.stages = stages;
  WriteTileReport(dir, doc);
  return report;
}

// A finished run whose recorded options still hold (SettingsStillHold), if there is one.
bool AlreadyDone(const std::string& dir, const RunOptions& o, StageReport* report) {
  const std::optional<TileReport> done = ReadTileReport(dir);
  const RunOptions defaults;
  if (!done || !SettingsStillHold(done->options.dump(), TileOptionsJson(o), TileOptionsJson(defaults))) return false;
  if (done->status == StageStatus::kFailed) return false;
  if (done->status == StageStatus::kOk && !fs::exists(fs::path(dir) / "splat" / "scene.ply")) return false;
  report->status = done->status;
  report->message = std::string("already done (") + ToString(done->status) + ")";
  return true;
}

// What sfm_options.json holds: the options, and the version of what the SfM
// writes (2: cameras.json carries each image's sun angles). An SfM of an
// older version is redone, not reused.
std::string SfmStamp(const SfmOptions& options) {
  return json{{"options", json::parse(SfmOptionsJson(options))}, {"outputs_version", 2}}.dump();
}

// The stamp the synthesis stage keeps its finished episodes under: the
// recorded one when it still holds for `options` (SettingsStillHold), so that
// an option added at its default does not discard them, else the options' own.
std::string IduStamp(const fs::path& tile_dir, const RunOptions& options) {
  const std::string current = IduEpisodesJson(options);
  const fs::path recorded_path = tile_dir / "idu" / "idu_options.json";  // RunIdu's stamp
  if (!fs::exists(recorded_path)) return current;
  const std::string recorded = ReadTextFile(recorded_path.string());
  const RunOptions defaults;
  return SettingsStillHold(recorded, current, IduEpisodesJson(defaults)) ? recorded : current;
}

// A finished SfM whose recorded options still hold (sfm_options.json is written after
// the SfM's own outputs, so a killed SfM is never taken as finished).
bool SfmDone(const fs::path& sfm_dir, const SfmOptions& options) {
  try {
    const json doc = json::parse(ReadTextFile((sfm_dir / "sfm_report.json").string()));
    return doc.value("status", "") == "ok" && fs::exists(sfm_dir / "points.ply") &&
           fs::exists(sfm_dir / "cameras.json") &&
           SettingsStillHold(ReadTextFile((sfm_dir / "sfm_options.json").string()), SfmStamp(options),
                             SfmStamp(SfmOptions()));
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

namespace {

// What the training job decided and why, for the tile report.
void AddTrainDecisions(const TrainStageOptions& train, const TrainDecisions& d, json* decisions) {
  json& out = *decisions;
  out["initial_points"] = d.dense_start ? "dense" : "sparse";
  // Dense cells kept at the dense grid's spacing beside steps (train.init_step_reach_m; 0 when off).
  out["initial_cells_beside_steps"] = d.init_fine_points;
  if (d.dense_start) out["initial_spacing"] = {{"m", d.init_spacing.value_m}, {"why", d.init_spacing.why}};
  out["train_downscale"] = {{"factor", d.downscale.factor}, {"why", d.downscale.why}};
  out["densify"] = {{"on", d.densify},
                    {"why", std::string("train.densify '") + EnumName(train.densify) + "', " +
                                (d.dense_start ? "dense" : "tie-point") + " start"}};
  out["appearance"] = {{"on", d.appearance}, {"why", d.appearance_reason}};
  out["surface_anchor"] = {
      {"on", d.surface_anchor},
      {"why", d.surface_anchor ? "dense start: training holds to the dense heights"
              : d.dense_start  ? "train.lambda_surface_* are 0"
                               : "no dense heights to hold to"}};
  out["mask_beyond_reconstruction"] = {
      {"on", train.mask_beyond_reconstruction && d.dense_start},
      {"masked_fraction", d.masked_beyond_fraction},
      {"why", !train.mask_beyond_reconstruction ? "train.mask_beyond_reconstruction is false"
              : d.dense_start ? "dense start: pixels seeing past the dense heights are not trained on or scored"
                              : "no dense heights to tell the tile's pixels from the rest"}};
  json by_view = json::object();
  for (const auto& [name, fraction] : d.cloud_masked_fraction) by_view[name] = fraction;
  out["cloud_mask"] = {{"on", d.cloud_mask}, {"why", d.cloud_mask_why}, {"masked_fraction_by_view", by_view}};
}

}  // namespace

StageReport RunTile(const std::string& tile_dir, const RunOptions& options, int threads, Progress& progress) {
  Stopwatch clock;
  options.Check();
  const TileSpec spec = ReadTileSpec((fs::path(tile_dir) / "tile.json").string());
  StageReport report;
  report.stage = "run-tile";
  if (AlreadyDone(tile_dir, options, &report)) return report;
  std::unique_ptr<tbb::global_control> thread_cap;
  if (threads > 0) {
    thread_cap = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  }
  if (spec.images.empty()) {
    report.status = StageStatus::kSkipped;
    report.message = spec.id + ": fewer than 2 images see this tile; nothing to reconstruct";
    return WriteReport(tile_dir, spec, options, report, {});
  }
  std::vector<StageReport> stages;
  const fs::path sfm_dir = fs::path(tile_dir) / "sfm";
  if (SfmDone(sfm_dir, options.sfm)) {
    stages.push_back(ReusedStage("sfm", "the finished SfM"));
  } else {
    const AoiCatalog catalog = ReadAoiCatalog((fs::path(tile_dir) / "aoi.json").string());
    fs::remove(sfm_dir / "sfm_options.json");  // until this SfM has finished
    const SfmResult sfm = RunSfmJob(options.sfm, catalog, sfm_dir.string(), false, progress);
    WriteFileAtomic((sfm_dir / "sfm_options.json").string(), SfmStamp(options.sfm));
    stages.push_back(sfm.report);
    if (sfm.report.status != StageStatus::kOk) {
      report.status = StageStatus::kDegenerate;
      report.message = spec.id + ": " + sfm.report.message;
      report.seconds = clock.Seconds();
      return WriteReport(tile_dir, spec, options, report, stages);
    }
  }
  CrashPoint("sfm");
  json decisions = json::object();
  // What fixed the tile's absolute position (the images' RPC average, the
  // acquisitions every tile of the city holds, or an anchor image), as the
  // SfM that made its cameras, run now or before, recorded it.
  const json sfm_record = ReadRecordOrNull((sfm_dir / "sfm_report.json").string());
  if (sfm_record.contains("absolute_position")) decisions["absolute_position"] = sfm_record["absolute_position"];
  if (options.train.init_points == InitPoints::kSparse) {
    decisions["dense"] = {{"ran", false}, {"why", "train.init_points is 'sparse'"}};
  } else if (DenseDone(sfm_dir.string(), options.dense, spec.extent)) {
    stages.push_back(ReusedStage("dense", "the finished dense heights"));
  } else {
    const DenseResult dense = RunDenseJob(options.dense, sfm_dir.string(), progress, spec.extent);
    stages.push_back(dense.report);
    if (dense.report.status != StageStatus::kOk) progress.Warn(spec.id + ": " + dense.report.message);
  }
  CrashPoint("dense");
  const TrainJobResult trained = RunTrainJob(options.train, sfm_dir.string(), (fs::path(tile_dir) / "splat").string(),
                                             progress);
  AddTrainDecisions(options.train, trained.decisions, &decisions);
  StageReport splat = trained.train.report;
  splat.stage = "splat";
  splat.metrics["gaussians"] = static_cast<double>(trained.train.cloud.size());
  if (!trained.train.series.empty()) splat.metrics["psnr_test_db"] = trained.train.series.back().psnr_test_db;
  stages.push_back(splat);
  const IduJobResult idu = RunIduJob(options.idu, options.train, sfm_dir.string(),
                                     (fs::path(tile_dir) / "splat" / "scene.ply").string(), spec.ReconstructedCore(),
                                     (fs::path(tile_dir) / "idu").string(), IduStamp(tile_dir, options), progress);
  decisions["idu"] = {{"on", idu.decision.on}, {"why", idu.decision.why},
                      {"facade_ratio", idu.decision.facade_ratio},
                      {"measured_fraction", idu.decision.measured_fraction}};
  CrashPoint("idu");
  std::size_t gaussians = trained.train.cloud.size();
  if (idu.decision.on) {
    StageReport synthesis = idu.idu.report;
    gaussians = idu.idu.cloud.size();
    stages.push_back(synthesis);
  }
  report.seconds = clock.Seconds();
  report.metrics["gaussians"] = static_cast<double>(gaussians);
  CrashPoint("tile");
  return WriteReport(tile_dir, spec, options, report, stages, decisions);
}

namespace {

// [MB] memory a tile run needs: a base (code, TBB, SfM tracks) plus per
// full-resolution crop pixel (SIFT pyramids and float training images),
// which covers the peaks measured on a real AOI (decision D-022).
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

// Tells the user how a tile ended and advances the tile count.
void ReportOutcome(const TileOutcome& o, std::size_t done, Progress& progress) {
  const std::string name = fs::path(o.dir).filename().string();
  if (o.exit_code == kExitDegenerate) {
    progress.Warn("tile " + name + " is degenerate (too little data); see " + o.dir + "/tile_report.json");
  } else if (o.exit_code != 0) {
    progress.Warn("tile " + name + " failed (exit " + std::to_string(o.exit_code) + "): " + o.message);
  }
  progress.Advance(done, fmt::format("{} exit {} {:.0f} s", name, o.exit_code, o.seconds));
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

namespace {

// The skyfall executable that runs a tile: the configured one, this program
// when it is skyfall, or a skyfall beside this program.
std::string TileProgram(const ExecutorOptions& executor) {
  if (!executor.program.empty()) {
    if (access(executor.program.c_str(), X_OK) != 0)
      throw Error("run", "executor.program", "'" + executor.program + "' is not an executable file");
    return executor.program;
  }
  const fs::path self = fs::read_symlink("/proc/self/exe");
  if (self.filename() == "skyfall") return self.string();
  for (const fs::path& candidate : {self.parent_path() / "skyfall", self.parent_path().parent_path() / "bin" / "skyfall"}) {
    if (access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  throw Error("run", "executor.program",
              "no skyfall executable beside " + self.string() + ": set executor.program, or use executor.kind 'inline'");
}

std::vector<TileOutcome> RunTilesAsProcesses(const std::vector<std::string>& tile_dirs, const RunOptions& options,
                                             const std::string& config_path, Progress& progress) {
  std::string why;
  const int jobs = ParallelTileJobs(tile_dirs, options.executor.jobs, &why);
  progress.Info(why);
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int threads = std::max(1, cores / std::max(1, jobs));
  const std::string program = TileProgram(options.executor);
  std::vector<TileOutcome> outcomes(tile_dirs.size());
  std::map<pid_t, std::pair<std::size_t, std::chrono::steady_clock::time_point>> running;
  std::size_t next = 0, done = 0;
  progress.Begin("tiles", tile_dirs.size());
  // The tile processes die with this one (see kParentPidEnv), so a rerun
  // after a kill never races with orphans writing the same tiles.
  const std::string parent = std::string(kParentPidEnv) + "=" + std::to_string(getpid());
  std::vector<char*> child_env;
  for (char** e = environ; *e; ++e) {
    if (std::strncmp(*e, kParentPidEnv, std::strlen(kParentPidEnv)) != 0) child_env.push_back(*e);
  }
  child_env.push_back(const_cast<char*>(parent.c_str()));
  child_env.push_back(nullptr);
  auto launch = [&](std::size_t k) {
    outcomes[k].dir = tile_dirs[k];
    std::vector<std::string> args = {program, "-q", "run-tile", tile_dirs[k], "--config", config_path,
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
    const int rc = posix_spawn(&pid, program.c_str(), &actions, nullptr, argv.data(), child_env.data());
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
    ReportOutcome(o, ++done, progress);
  }
  progress.End();
  return outcomes;
}

std::vector<TileOutcome> RunTilesInline(const std::vector<std::string>& tile_dirs, const RunOptions& options,
                                        Progress& progress) {
  std::vector<TileOutcome> outcomes(tile_dirs.size());
  NullProgress quiet;  // the tiles' own progress would interleave with the tile count
  progress.Begin("tiles", tile_dirs.size());
  for (std::size_t k = 0; k < tile_dirs.size(); ++k) {
    TileOutcome& o = outcomes[k];
    o.dir = tile_dirs[k];
    Stopwatch clock;
    try {
      o.exit_code = ExitCodeOf(RunTile(o.dir, options, 0, quiet).status);
    } catch (const Error& e) {
      o.exit_code = kExitBadInput;
      o.message = e.what();
    } catch (const std::exception& e) {
      o.exit_code = kExitInternal;
      o.message = std::string("internal error: ") + e.what();
    }
    o.seconds = clock.Seconds();
    ReportOutcome(o, k + 1, progress);
  }
  progress.End();
  return outcomes;
}

// Runs a city's tiles: each as its own `skyfall run-tile` process, or one
// after the other in this process.
class TileExecutor {
 public:
  virtual ~TileExecutor() = default;
  virtual std::vector<TileOutcome> Run(const std::vector<std::string>& tile_dirs, const RunOptions& options,
                                       const std::string& config_path, Progress& progress) const = 0;
};

class ProcessTileExecutor final : public TileExecutor {
 public:
  std::vector<TileOutcome> Run(const std::vector<std::string>& tile_dirs, const RunOptions& options,
                               const std::string& config_path, Progress& progress) const override {
    return RunTilesAsProcesses(tile_dirs, options, config_path, progress);
  }
};

class InlineTileExecutor final : public TileExecutor {
 public:
  std::vector<TileOutcome> Run(const std::vector<std::string>& tile_dirs, const RunOptions& options,
                               const std::string& /*config_path*/, Progress& progress) const override {
    return RunTilesInline(tile_dirs, options, progress);
  }
};

std::unique_ptr<TileExecutor> MakeTileExecutor(ExecutorKind kind) {
  switch (kind) {
    case ExecutorKind::kLocal: return std::make_unique<ProcessTileExecutor>();
    case ExecutorKind::kInline: return std::make_unique<InlineTileExecutor>();
    case ExecutorKind::kSlurm: break;
  }
  throw Error("run", "executor.kind", "slurm runs whole cities (RunCity), not RunTiles");
}

}  // namespace

void DieWithParentIfAsked() {
  const char* parent = std::getenv(kParentPidEnv);
  if (!parent || !*parent) return;
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  // The parent may have died before the request took effect.
  if (getppid() != static_cast<pid_t>(std::strtol(parent, nullptr, 10))) _exit(kExitInternal);
}

double EstimatedTileMemoryMb(const std::string& tile_dir) { return TileMemoryMb(tile_dir); }

std::string TileProgramPath(const ExecutorOptions& executor) { return TileProgram(executor); }

bool TileFinished(const std::string& tile_dir, const RunOptions& options) {
  StageReport unused;
  return AlreadyDone(tile_dir, options, &unused);
}

TileOutcome TileOutcomeFromReport(const std::string& tile_dir) {
  TileOutcome o;
  o.dir = tile_dir;
  const std::optional<TileReport> report = ReadTileReport(tile_dir);
  if (!report) {
    o.exit_code = kExitBadInput;
    o.message = "no tile report: the tile did not finish; see " + (fs::path(tile_dir) / "run.log").string();
    return o;
  }
  o.exit_code = report->status == StageStatus::kDegenerate ? kExitDegenerate
                : report->status == StageStatus::kFailed   ? kExitBadInput
                                                            : kExitOk;
  o.seconds = report->seconds;
  o.message = report->message;
  return o;
}

std::vector<TileOutcome> RunTiles(const std::vector<std::string>& tile_dirs, const RunOptions& options,
                                  const std::string& config_path, Progress& progress) {
  options.executor.Check();
  return MakeTileExecutor(options.executor.kind)->Run(tile_dirs, options, config_path, progress);
}

}  // namespace skyfall
