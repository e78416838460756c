// An exclusive lock on a run's output folder, so that two cron runs never
// write the same products. It is a flock(2) on OUT/.skyfall.lock: the kernel
// releases it when the holding process dies, however it dies, so a crashed
// run never leaves a stale lock behind. The file also names the holder (PID,
// host, start time) for the message the refused run prints.
#pragma once

#include <optional>
#include <string>

namespace skyfall {

// Who holds a lock, as written into the lock file by the holder.
struct LockHolder {
  long pid = 0;
  std::string host;
  std::string started_utc;  // ISO 8601
};

class OutputLock {
 public:
  // Takes the lock on `out_dir` (created when missing), waiting up to
  // `wait_s` seconds (0 = do not wait). Returns nullopt when another process
  // still holds it; `holder` then tells who. Throws Error naming the file when
  // the folder or lock file cannot be created.
  static std::optional<OutputLock> Acquire(const std::string& out_dir, double wait_s, LockHolder* holder);

  OutputLock(OutputLock&& other) noexcept;
  OutputLock& operator=(OutputLock&&) = delete;
  OutputLock(const OutputLock&) = delete;
  ~OutputLock();

  const std::string& path() const { return path_; }

 private:
  OutputLock(int fd, std::string path) : fd_(fd), path_(std::move(path)) {}
  int fd_ = -1;
  std::string path_;
};

// The lock file's name inside an output folder.
inline constexpr const char* kLockFileName = ".skyfall.lock";

// One line for the user: "held by PID 123 on host since 2026-...".
std::string DescribeHolder(const LockHolder& holder);

}  // namespace skyfall
