#include "apps/console.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

namespace skyfall::cli {

void SetupLogging(bool quiet, bool verbose) {
  auto logger = spdlog::stderr_color_mt("skyfall");
  logger->set_pattern("%^[%H:%M:%S %L]%$ %v");
  spdlog::set_default_logger(logger);
  spdlog::set_level(quiet ? spdlog::level::warn
                          : (verbose ? spdlog::level::debug : spdlog::level::info));
}

void ConsoleProgress::Begin(std::string_view task, std::size_t total) {
  task_ = task;
  total_ = total;
  done_ = 0;
  clock_ = Stopwatch();
  last_print_s_ = -1.0;
  spdlog::info("[{}] start ({} items)", task_, total_);
}

void ConsoleProgress::Advance(std::size_t done, std::string_view item) {
  done_ = done;
  constexpr double kMinSecondsBetweenLines = 0.5;
  const double now = clock_.Seconds();
  if (now - last_print_s_ < kMinSecondsBetweenLines && done != total_) {
    spdlog::debug("[{}] {}/{} {}", task_, done, total_, item);
    return;
  }
  last_print_s_ = now;
  spdlog::info("[{}] {}/{} {}", task_, done, total_, item);
}

void ConsoleProgress::Warn(std::string_view message) { spdlog::warn("{}", message); }

void ConsoleProgress::Info(std::string_view message) { spdlog::info("{}", message); }

void ConsoleProgress::End() {
  spdlog::info("[{}] done: {}/{} in {:.1f} s", task_, done_, total_, clock_.Seconds());
}

}  // namespace skyfall::cli
