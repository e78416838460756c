// The small pieces of a city's run report and event log that its stages
// share: a stage's entry and an event with figures.
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "core/stage.h"

namespace skyfall {

inline nlohmann::json StageEntry(const std::string& stage, const std::string& status, double seconds,
                                 const std::string& message = "") {
  return {{"stage", stage}, {"status", status}, {"seconds", seconds}, {"message", message}};
}

inline void Emit(Progress& progress, const std::string& level, const std::string& stage, const std::string& aoi,
                 const std::string& tile, const std::string& message, std::map<std::string, double> figures = {}) {
  progress.Record({level, stage, aoi, tile, message, std::move(figures)});
}

}  // namespace skyfall
