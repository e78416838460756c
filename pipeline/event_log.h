// Machine-readable events for log collectors (`--log-json FILE`): one JSON
// object per line, appended and flushed as it happens, so a tail -f or a
// collector sees every event even if the run is killed:
//   {"time": "2026-11-23T18:00:00.123Z", "level": "info", "stage": "tiles",
//    "aoi": "JAX_068", "tile": "JAX_068_c0_r0", "message": "...",
//    "figures": {"seconds": 12.5}}
// Empty stage/aoi/tile are left out; figures are named with their units.
#pragma once

#include <map>
#include <mutex>
#include <string>

namespace skyfall {

struct Event {
  std::string level = "info";  // "debug", "info", "warning", "error"
  std::string stage;
  std::string aoi;   // AOI or city
  std::string tile;
  std::string message;
  std::map<std::string, double> figures;
};

// The process's event log; disabled (every Write a no-op) until opened.
class EventLog {
 public:
  // Opens `path` for appending (created when missing). Throws Error naming
  // the path when it cannot be opened.
  void Open(const std::string& path);
  bool enabled() const { return fd_ >= 0; }
  // One line, written with a single append so concurrent writers (threads or
  // processes sharing the file) never interleave within a line.
  void Write(const Event& event);
  ~EventLog();

 private:
  int fd_ = -1;
  std::mutex mutex_;
};

// The process-wide log the CLI opens and the pipeline writes to.
EventLog& Events();

// The JSON text of an event (no newline); `time_utc` is ISO 8601.
std::string EventJson(const Event& event, const std::string& time_utc);

}  // namespace skyfall
