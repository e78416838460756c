#include "core/format.h"

#include <chrono>
#include <cstdio>
#include <ctime>

#include <cctype>
#include <cstdio>
#include <cstdlib>

namespace skyfall {

std::string FormatDouble(double value) {
  char buf[40];
  // Try increasing precision until the text round-trips: short for simple
  // numbers ("0.5"), exact for everything.
  for (int precision = 15; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, value);
    if (std::strtod(buf, nullptr) == value) break;
  }
  return buf;
}

std::string ToLower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

std::string UtcNowIso(bool milliseconds) {
  const auto now = std::chrono::system_clock::now();
  const std::time_t seconds = std::chrono::system_clock::to_time_t(now);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char text[40];
  std::size_t n = std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%S", &utc);
  if (milliseconds) {
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
    n += std::snprintf(text + n, sizeof text - n, ".%03d", static_cast<int>(ms));
  }
  std::snprintf(text + n, sizeof text - n, "Z");
  return text;
}

}  // namespace skyfall
