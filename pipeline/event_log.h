// Machine-readable events for log collectors (`--log-json FILE`): one JSON
// object per line, appended and flushed as it happens, so a tail -f or a
// collector sees every event even if the run is killed:
//   {"time": "2026-11-23T18:00:00.123Z", "level": "info", "stage": "tiles",
//    "aoi": "JAX_068", "tile": "JAX_068_c0_r0", "message": "...",
//    "figures": {"seconds": 12.5}}
// Empty stage/aoi/tile are left out; figures are named with their units.
#pragma once

#include <mutex>
#include <string>

#include "core/stage.h"

namespace skyfall {

// An event log file (Event: core/stage.h); disabled (every Write a no-op)
// until opened. Libraries never write one: they pass events to their
// Progress sink, and the CLI's sink writes them here.
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

// The JSON text of an event (no newline); `time_utc` is ISO 8601.
std::string EventJson(const Event& event, const std::string& time_utc);

}  // namespace skyfall
