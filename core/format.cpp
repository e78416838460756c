#include "core/format.h"

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

}  // namespace skyfall
