#include "pipeline/output_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <thread>

#include "core/error.h"
#include "core/format.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

std::string HostName() {
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) != 0) return "unknown";
  return name;
}

// The holder's record: "pid=<n>\nhost=<h>\nstarted=<iso>\n". The holder
// writes it right after taking the lock, so it may still be empty when read.
LockHolder ReadHolder(int fd) {
  LockHolder holder;
  char buffer[512] = {};
  const ssize_t n = pread(fd, buffer, sizeof buffer - 1, 0);
  if (n <= 0) return holder;
  std::istringstream in(std::string(buffer, static_cast<std::size_t>(n)));
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = line.substr(0, eq), value = line.substr(eq + 1);
    if (key == "pid") holder.pid = std::strtol(value.c_str(), nullptr, 10);
    if (key == "host") holder.host = value;
    if (key == "started") holder.started_utc = value;
  }
  return holder;
}

void WriteHolder(int fd, const std::string& path) {
  const std::string record =
      "pid=" + std::to_string(getpid()) + "\nhost=" + HostName() + "\nstarted=" + UtcNowIso() + "\n";
  if (ftruncate(fd, 0) != 0 || pwrite(fd, record.data(), record.size(), 0) != static_cast<ssize_t>(record.size())) {
    throw Error("run", path, std::string("cannot write the lock file: ") + std::strerror(errno));
  }
}

}  // namespace

std::optional<OutputLock> OutputLock::Acquire(const std::string& out_dir, double wait_s, LockHolder* holder) {
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  const std::string path = (fs::path(out_dir) / kLockFileName).string();
  if (ec) throw Error("run", out_dir, "cannot create the output folder: " + ec.message());
  // O_CLOEXEC: tile processes must not inherit the lock, or a killed run
  // would keep its folder locked until its children end.
  const int fd = open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw Error("run", path, std::string("cannot open the lock file: ") + std::strerror(errno));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
  constexpr auto kPollInterval = std::chrono::milliseconds(200);
  while (flock(fd, LOCK_EX | LOCK_NB) != 0) {
    if (errno != EWOULDBLOCK && errno != EINTR) {
      const int err = errno;
      close(fd);
      throw Error("run", path, std::string("cannot lock: ") + std::strerror(err));
    }
    if (std::chrono::steady_clock::now() >= deadline) {
      if (holder) *holder = ReadHolder(fd);
      close(fd);
      return std::nullopt;
    }
    std::this_thread::sleep_for(kPollInterval);
  }
  try {
    WriteHolder(fd, path);
  } catch (...) {
    close(fd);
    throw;
  }
  return OutputLock(fd, path);
}

OutputLock::OutputLock(OutputLock&& other) noexcept : fd_(other.fd_), path_(std::move(other.path_)) { other.fd_ = -1; }

OutputLock::~OutputLock() {
  if (fd_ >= 0) close(fd_);  // closing the last descriptor releases the flock
}

std::string DescribeHolder(const LockHolder& holder) {
  if (holder.pid == 0) return "held by a run that is just starting";
  std::string text = "held by PID " + std::to_string(holder.pid);
  if (!holder.host.empty()) text += " on " + holder.host;
  if (!holder.started_utc.empty()) text += " since " + holder.started_utc;
  return text;
}

}  // namespace skyfall
