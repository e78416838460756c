#include "pipeline/event_log.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/format.h"

namespace skyfall {
std::string EventJson(const Event& event, const std::string& time_utc) {
  nlohmann::json doc = {{"time", time_utc}, {"level", event.level}};
  if (!event.stage.empty()) doc["stage"] = event.stage;
  if (!event.aoi.empty()) doc["aoi"] = event.aoi;
  if (!event.tile.empty()) doc["tile"] = event.tile;
  doc["message"] = event.message;
  nlohmann::json figures = nlohmann::json::object();
  for (const auto& [name, value] : event.figures) figures[name] = std::isfinite(value) ? nlohmann::json(value) : nullptr;
  doc["figures"] = figures;
  // Invalid UTF-8 in a message (a path from the disk) is replaced, not fatal.
  return doc.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

void EventLog::Open(const std::string& path) {
  std::lock_guard<std::mutex> lock(mutex_);
  const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) throw Error("log", path, std::string("cannot open the JSON log: ") + std::strerror(errno));
  if (fd_ >= 0) close(fd_);
  fd_ = fd;
}

void EventLog::Write(const Event& event) {
  if (fd_ < 0) return;
  const std::string line = EventJson(event, UtcNowIso(true)) + "\n";
  std::lock_guard<std::mutex> lock(mutex_);
  // A log that cannot be written (full disk) must not stop the run.
  [[maybe_unused]] const ssize_t written = write(fd_, line.data(), line.size());
}

EventLog::~EventLog() {
  if (fd_ >= 0) close(fd_);
}

}  // namespace skyfall
