#include "apps/console.h"

#include <spdlog/sinks/base_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <unistd.h>

#include <mutex>


namespace skyfall::cli {
namespace {

const char* LevelName(spdlog::level::level_enum level) {
  switch (level) {
    case spdlog::level::trace:
    case spdlog::level::debug: return "debug";
    case spdlog::level::warn: return "warning";
    case spdlog::level::err:
    case spdlog::level::critical: return "error";
    default: return "info";
  }
}

// Every human log line also goes into the JSON event log, as an event of
// stage "log" (the pipeline adds structured events of its own).
class EventLogSink final : public spdlog::sinks::base_sink<std::mutex> {
 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    Event event;
    event.level = LevelName(msg.level);
    event.stage = "log";
    event.message.assign(msg.payload.data(), msg.payload.size());
    CliEventLog().Write(event);
  }
  void flush_() override {}
};

}  // namespace

EventLog& CliEventLog() {
  static EventLog log;
  return log;
}

void ConsoleProgress::Record(const Event& event) { CliEventLog().Write(event); }

void SetupLogging(bool quiet, bool verbose, const std::string& log_json_path) {
  auto console = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
  console->set_pattern("%^[%H:%M:%S %L]%$ %v");
  console->set_level(quiet ? spdlog::level::warn : (verbose ? spdlog::level::debug : spdlog::level::info));
  std::vector<spdlog::sink_ptr> sinks{console};
  if (!log_json_path.empty()) {
    CliEventLog().Open(log_json_path);
    auto json_sink = std::make_shared<EventLogSink>();
    json_sink->set_level(verbose ? spdlog::level::debug : spdlog::level::info);
    sinks.push_back(json_sink);
  }
  auto logger = std::make_shared<spdlog::logger>("skyfall", sinks.begin(), sinks.end());
  logger->set_level(verbose ? spdlog::level::debug : spdlog::level::info);
  spdlog::set_default_logger(logger);
}

void ConsoleProgress::Begin(std::string_view task, std::size_t total) {
  task_ = task;
  total_ = total;
  done_ = 0;
  clock_ = Stopwatch();
  last_print_s_ = -1.0;
  last_print_fraction_ = 0.0;
  spdlog::info("[{}] start ({} items)", task_, total_);
}

void ConsoleProgress::Advance(std::size_t done, std::string_view item) {
  done_ = done;
  const double now = clock_.Seconds();
  if (!DueForLine(now, done)) {
    spdlog::debug("[{}] {}/{} {}", task_, done, total_, item);
    return;
  }
  last_print_s_ = now;
  last_print_fraction_ = total_ ? static_cast<double>(done) / total_ : 0.0;
  spdlog::info("[{}] {}/{} {}", task_, done, total_, item);
}

bool ConsoleProgress::DueForLine(double now_s, std::size_t done) const {
  if (done == total_) return true;
  // A person at a terminal sees a line at most twice a second; a log file
  // (cron, a tile's run.log) gets one every 10 s or every 5 % of the task.
  static const bool terminal = isatty(STDERR_FILENO) != 0;
  constexpr double kTerminalSeconds = 0.5, kLogSeconds = 10.0, kLogFraction = 0.05;
  if (terminal) return now_s - last_print_s_ >= kTerminalSeconds;
  const double fraction = total_ ? static_cast<double>(done) / total_ : 0.0;
  return last_print_s_ < 0 || now_s - last_print_s_ >= kLogSeconds || fraction - last_print_fraction_ >= kLogFraction;
}

void ConsoleProgress::Warn(std::string_view message) { spdlog::warn("{}", message); }

void ConsoleProgress::Info(std::string_view message) { spdlog::info("{}", message); }

void ConsoleProgress::End() {
  spdlog::info("[{}] done: {}/{} in {:.1f} s", task_, done_, total_, clock_.Seconds());
}

}  // namespace skyfall::cli
