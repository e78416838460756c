// What every stage returns besides its product, and how it reports progress.
// Libraries never print: they fill a StageReport and call a Progress sink; the
// CLI decides what to show.
#pragma once

#include <chrono>
#include <cstddef>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace skyfall {

enum class StageStatus { kOk, kSkipped, kDegenerate, kFailed };

const char* ToString(StageStatus status);

struct StageReport {
  std::string stage;                       // "ingest", "sfm", ...
  StageStatus status = StageStatus::kOk;
  std::string message;                     // one line for the user; empty when ok
  std::map<std::string, double> metrics;   // named figures, units in the name
  std::vector<std::string> warnings;       // problems that did not stop the stage
  double seconds = 0.0;                    // wall time of the stage
};

// A machine-readable record of something that happened, for log collectors
// (the CLI's --log-json): figures are named with their units; empty
// stage/aoi/tile are left out when written.
struct Event {
  std::string level = "info";  // "debug", "info", "warning", "error"
  std::string stage;
  std::string aoi;   // AOI or city
  std::string tile;
  std::string message;
  std::map<std::string, double> figures;
};

// Progress sink for long work. Every method has an empty default so a stage
// can be called with a NullProgress in tests. Implementations must be cheap:
// stages call Advance once per item.
class Progress {
 public:
  virtual ~Progress() = default;
  // A new task with `total` items (0 when unknown).
  virtual void Begin(std::string_view task, std::size_t total) {}
  // `done` items finished so far; `item` names the one just finished.
  virtual void Advance(std::size_t done, std::string_view item) {}
  // Something went wrong with one item but the task goes on.
  virtual void Warn(std::string_view message) {}
  // A line worth telling the user that is not a problem (a decision, a summary).
  virtual void Info(std::string_view message) {}
  // A structured event; the caller decides where events go.
  virtual void Record(const Event& event) {}
  virtual void End() {}
};

class NullProgress final : public Progress {};

// Measures wall time for StageReport::seconds.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double Seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace skyfall
