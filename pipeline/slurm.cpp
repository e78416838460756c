#include "pipeline/slurm.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "core/atomic_file.h"
#include "core/error.h"
#include "products/stac.h"
#include "pipeline/tile_run.h"

extern char** environ;

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// [MB] memory below which a tile job is never sized: the process itself,
// GDAL and TBB, whatever the crops.
constexpr double kMinJobMemoryMb = 1024.0;

std::string Trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  std::size_t start = 0;
  while (start < s.size() && std::isspace(static_cast<unsigned char>(s[start]))) ++start;
  return s.substr(start);
}

// The #SBATCH lines every job of the city shares.
std::string ResourceLines(const SlurmOptions& slurm, int mem_mb) {
  std::string lines = "#SBATCH --cpus-per-task=" + std::to_string(slurm.cpus_per_task) + "\n";
  lines += "#SBATCH --mem=" + std::to_string(mem_mb) + "M\n";
  if (!slurm.time_limit.empty()) lines += "#SBATCH --time=" + slurm.time_limit + "\n";
  if (!slurm.partition.empty()) lines += "#SBATCH --partition=" + slurm.partition + "\n";
  if (!slurm.account.empty()) lines += "#SBATCH --account=" + slurm.account + "\n";
  return lines;
}

std::string TilesScript(const std::string& city, const fs::path& slurm_dir, const std::string& program,
                        const std::string& config_path, const std::string& resources) {
  return "#!/bin/bash\n"
         "#SBATCH --job-name=skyfall-tiles-" + city + "\n"
         "#SBATCH --output=" + (slurm_dir / "tile_%A_%a.out").string() + "\n" + resources +
         "# One task per line of tiles.txt: that tile's SfM, dense heights, training and synthesis.\n"
         "tile=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" " + ShellQuote((slurm_dir / "tiles.txt").string()) + ")\n"
         "[ -n \"$tile\" ] || { echo \"no tile for task $SLURM_ARRAY_TASK_ID\" >&2; exit 1; }\n" +
         ShellQuote(program) + " -q run-tile \"$tile\" --config " + ShellQuote(config_path) +
         " --threads \"${SLURM_CPUS_PER_TASK:-1}\" >>\"$tile/run.log\" 2>&1\n"
         "rc=$?\n"
         "# A degenerate tile (too little data, exit 4) is finished, not failed: the merge goes on.\n"
         "if [ \"$rc\" -eq 4 ]; then exit 0; fi\n"
         "exit \"$rc\"\n";
}

std::string FinishScript(const std::string& city, const fs::path& city_dir, const fs::path& slurm_dir,
                         const std::string& program, const std::string& resources) {
  return "#!/bin/bash\n"
         "#SBATCH --job-name=skyfall-finish-" + city + "\n"
         "#SBATCH --output=" + (slurm_dir / "finish_%j.out").string() + "\n" + resources +
         "# The city's merge with LOD, DSM export and comparison, run report and STAC catalog.\n"
         "exec " + ShellQuote(program) + " finish-city " + ShellQuote(city_dir.string()) + "\n";
}

// sbatch --parsable prints "<id>" or "<id>;<cluster>".
std::string Submit(const std::vector<std::string>& argv) {
  std::string output;
  const int rc = RunProgram(argv, &output);
  const std::string id = Trim(output.substr(0, output.find(';')));
  if (rc != 0 || id.empty() || !std::all_of(id.begin(), id.end(), ::isdigit)) {
    std::string command;
    for (const auto& a : argv) command += (command.empty() ? "" : " ") + a;
    throw Error("slurm", command, "sbatch failed (exit " + std::to_string(rc) + "): " + Trim(output));
  }
  return id;
}

}  // namespace

std::string ShellQuote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

int RunProgram(const std::vector<std::string>& argv, std::string* output) {
  int pipe_fds[2];
  if (pipe2(pipe_fds, O_CLOEXEC) != 0) throw Error("slurm", argv.at(0), std::string("pipe: ") + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], STDERR_FILENO);
  std::vector<std::string> args = argv;
  std::vector<char*> cargs;
  for (auto& a : args) cargs.push_back(a.data());
  cargs.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, args[0].c_str(), &actions, nullptr, cargs.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(pipe_fds[1]);
  if (rc != 0) {
    close(pipe_fds[0]);
    throw Error("slurm", argv[0], std::string("cannot run: ") + std::strerror(rc) + " (is Slurm installed?)");
  }
  output->clear();
  char buffer[4096];
  ssize_t n;
  while ((n = read(pipe_fds[0], buffer, sizeof buffer)) > 0 || (n < 0 && errno == EINTR)) {
    if (n > 0) output->append(buffer, static_cast<std::size_t>(n));
  }
  close(pipe_fds[0]);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

SlurmCityJobs SubmitSlurmCity(const RunOptions& options, const std::string& city_dir,
                              const std::vector<std::string>& unfinished_tiles, const std::string& config_path) {
  const fs::path dir(city_dir), slurm_dir = dir / "slurm";
  fs::create_directories(slurm_dir);
  const std::string city = dir.filename().string();
  const std::string program = fs::absolute(TileProgramPath(options.executor)).string();
  double mem_mb = options.executor.slurm.mem_mb;
  if (mem_mb <= 0) {
    mem_mb = kMinJobMemoryMb;
    for (const auto& t : unfinished_tiles) mem_mb = std::max(mem_mb, EstimatedTileMemoryMb(t));
  }
  const std::string resources = ResourceLines(options.executor.slurm, static_cast<int>(std::ceil(mem_mb)));
  SlurmCityJobs jobs;
  jobs.tiles = unfinished_tiles;
  jobs.submitted_utc = UtcNowIso();
  std::string tiles_txt;
  for (const auto& t : unfinished_tiles) tiles_txt += fs::absolute(t).string() + "\n";
  WriteFileAtomic((slurm_dir / "tiles.txt").string(), tiles_txt);
  const std::string tiles_script = (slurm_dir / "tiles.sbatch").string();
  const std::string finish_script = (slurm_dir / "finish.sbatch").string();
  WriteFileAtomic(tiles_script,
                  TilesScript(city, fs::absolute(slurm_dir), program, fs::absolute(config_path).string(), resources));
  WriteFileAtomic(finish_script, FinishScript(city, fs::absolute(dir), fs::absolute(slurm_dir), program, resources));
  if (!unfinished_tiles.empty()) {
    jobs.tiles_job = Submit({"sbatch", "--parsable", "--array=0-" + std::to_string(unfinished_tiles.size() - 1),
                             tiles_script});
  }
  std::vector<std::string> finish = {"sbatch", "--parsable"};
  if (!jobs.tiles_job.empty()) finish.push_back("--dependency=afterok:" + jobs.tiles_job);
  finish.push_back(finish_script);
  jobs.finish_job = Submit(finish);
  const json doc = {{"schema", "skyfall.slurm_jobs/1"}, {"tiles_job", jobs.tiles_job},
                    {"finish_job", jobs.finish_job}, {"tiles", jobs.tiles}, {"submitted_utc", jobs.submitted_utc}};
  WriteFileAtomic((slurm_dir / "jobs.json").string(), doc.dump(2) + "\n");
  return jobs;
}

bool ReadSlurmJobs(const std::string& city_dir, SlurmCityJobs* jobs) {
  const fs::path path = fs::path(city_dir) / "slurm" / "jobs.json";
  if (!fs::exists(path)) return false;
  try {
    const json doc = json::parse(ReadTextFile(path.string()));
    jobs->tiles_job = doc.at("tiles_job");
    jobs->finish_job = doc.at("finish_job");
    jobs->tiles = doc.at("tiles").get<std::vector<std::string>>();
    jobs->submitted_utc = doc.value("submitted_utc", "");
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

std::string SlurmJobState(const std::string& job_id) {
  std::string output;
  // A finished job is no longer listed (squeue may also exit non-zero for an
  // id it has forgotten): both mean "not queued".
  if (RunProgram({"squeue", "-h", "-j", job_id, "-o", "%T %r"}, &output) != 0) return "";
  std::istringstream lines(output);
  std::string line;
  std::getline(lines, line);
  line = Trim(line);
  if (line.size() > 5 && line.substr(line.size() - 5) == " None") line.resize(line.size() - 5);
  return line;
}

std::map<int, std::string> SlurmArrayTaskStates(const std::string& array_job_id) {
  std::map<int, std::string> states;
  std::string output;
  if (RunProgram({"squeue", "-h", "-r", "-j", array_job_id, "-o", "%K %T"}, &output) != 0) return states;
  std::istringstream lines(output);
  std::string task, state;
  while (lines >> task >> state) {
    if (!task.empty() && std::all_of(task.begin(), task.end(), ::isdigit)) states[std::stoi(task)] = state;
  }
  return states;
}

std::string HeldReason(const std::string& job_id) {
  std::string output;
  if (job_id.empty() || RunProgram({"squeue", "-h", "-r", "-j", job_id, "-o", "%T %r"}, &output) != 0) return "";
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);) {
    std::string lower = line;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
    if (lower.find("held") != std::string::npos) return Trim(line);
  }
  return "";
}

std::string WaitForSlurmJob(const std::string& job_id, const std::string& watched_job, double poll_s,
                            const std::function<void()>& on_poll) {
  std::string unused;
  while (true) {
    const std::string state = SlurmJobState(job_id);
    if (state.empty()) return "done";
    if (state.find("DependencyNeverSatisfied") != std::string::npos) {
      RunProgram({"scancel", job_id}, &unused);
      return "dependency_never_satisfied";
    }
    // A job that the scheduler holds (a launch that failed on the node, or an
    // administrator's hold) would wait forever: give up and say why.
    for (const std::string& id : {watched_job, job_id}) {
      const std::string held = HeldReason(id);
      if (held.empty()) continue;
      if (!watched_job.empty()) RunProgram({"scancel", watched_job}, &unused);
      RunProgram({"scancel", job_id}, &unused);
      return "held: job " + id + " " + held;
    }
    if (on_poll) on_poll();
    std::this_thread::sleep_for(std::chrono::duration<double>(poll_s));
  }
}

}  // namespace skyfall
