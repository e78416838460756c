// Logging and progress conventions of the CLI (every stage uses them):
//  - stdout carries only results (numbers, --json documents), so it can be
//    piped; everything for humans goes to stderr through spdlog.
//  - `-q` shows warnings and errors only, `-v` adds debug detail.
//  - Long work reports "[task] done/total item" lines on stderr: at most two
//    per second on a terminal, and when stderr is a file or pipe (cron,
//    tile logs) one every 10 s or 5 % of the task; plus a final line.
//    Skipped items are warnings.
#pragma once

#include <chrono>
#include <string>

#include "core/stage.h"
#include "pipeline/event_log.h"

namespace skyfall::cli {

// Sets up the global logger from the -q / -v flags; with a path, every log
// line also goes to the JSON event log there (see pipeline/event_log.h).
void SetupLogging(bool quiet, bool verbose, const std::string& log_json_path = "");

// The CLI's JSON event log (--log-json), opened by SetupLogging: log lines
// and the pipeline's events (through ConsoleProgress::Record) go there.
EventLog& CliEventLog();

class ConsoleProgress final : public Progress {
 public:
  void Begin(std::string_view task, std::size_t total) override;
  void Advance(std::size_t done, std::string_view item) override;
  void Warn(std::string_view message) override;
  void Info(std::string_view message) override;
  void Record(const Event& event) override;
  void End() override;

 private:
  std::string task_;
  std::size_t total_ = 0;
  std::size_t done_ = 0;
  // True when a progress line is due (see the conventions above).
  bool DueForLine(double now_s, std::size_t done) const;

  Stopwatch clock_;
  double last_print_s_ = -1.0;
  double last_print_fraction_ = 0.0;
};

}  // namespace skyfall::cli
