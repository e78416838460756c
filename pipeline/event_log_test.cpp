#include "pipeline/event_log.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "core/error.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

TEST(EventLog, OneJsonObjectPerLineWithEveryField) {
  const auto path = testing::ScratchDir("log") / "events.jsonl";
  EventLog log;
  log.Write({"info", "dsm", "A", "", "ignored while closed", {}});
  log.Open(path.string());
  log.Write({"info", "dsm", "JAX_068", "", "compared", {{"mae_m", 1.25}, {"nan_m", std::nan("")}}});
  std::vector<std::thread> writers;
  for (int t = 0; t < 4; ++t) {
    writers.emplace_back([&log, t] {
      for (int i = 0; i < 50; ++i) log.Write({"warning", "tile", "city", "t" + std::to_string(t), "x", {}});
    });
  }
  for (auto& w : writers) w.join();
  std::ifstream in(path);
  std::string line;
  int lines = 0;
  while (std::getline(in, line)) {
    const auto event = nlohmann::json::parse(line);  // every line is whole
    ASSERT_TRUE(event.contains("time"));
    if (lines++ == 0) {
      EXPECT_EQ(event["level"], "info");
      EXPECT_EQ(event["stage"], "dsm");
      EXPECT_EQ(event["aoi"], "JAX_068");
      EXPECT_FALSE(event.contains("tile"));  // empty fields are left out
      EXPECT_EQ(event["figures"]["mae_m"], 1.25);
      EXPECT_TRUE(event["figures"]["nan_m"].is_null());  // JSON has no NaN
      EXPECT_EQ(event["time"].get<std::string>().size(), 24u);  // 2026-11-23T18:00:00.123Z
    }
  }
  EXPECT_EQ(lines, 1 + 4 * 50);
}

TEST(EventLog, UnwritablePathIsANamedError) {
  EventLog log;
  const std::string error = testing::ErrorText([&] { log.Open("/nonexistent/dir/events.jsonl"); });
  EXPECT_NE(error.find("/nonexistent/dir/events.jsonl"), std::string::npos) << error;
}

}  // namespace
}  // namespace skyfall
