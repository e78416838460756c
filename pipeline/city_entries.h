// The small pieces the run's reports and event log share: a stage's entry,
// an event with figures, and a figure that may be undefined.
#pragma once

#include <sys/resource.h>

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "core/stage.h"

namespace skyfall {

// [MiB] this process's peak resident memory so far (the kernel's high-water
// mark: it never falls, so a stage's figure is the peak up to its end).
inline double PeakSelfRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

// A stage of the city's run; `peak_rss_mb` is the running process's peak up
// to the stage's end (tile processes report their own in `tiles[]`).
inline nlohmann::json StageEntry(const std::string& stage, const std::string& status, double seconds,
                                 const std::string& message = "") {
  return {{"stage", stage}, {"status", status}, {"seconds", seconds}, {"message", message},
          {"peak_rss_mb", PeakSelfRssMb()}};
}

// A figure as JSON: null where it is NaN or infinite (JSON has no NaN).
inline nlohmann::json FiniteOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

inline void Emit(Progress& progress, const std::string& level, const std::string& stage, const std::string& aoi,
                 const std::string& tile, const std::string& message, std::map<std::string, double> figures = {}) {
  progress.Record({level, stage, aoi, tile, message, std::move(figures)});
}

}  // namespace skyfall
