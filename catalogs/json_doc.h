// JSON helpers shared by the readers of catalogs and camera files.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>

#include "core/error.h"

namespace skyfall::catalogs {

// Parses a versioned catalog document; throws Error("catalog", subject, ...)
// when it is not JSON or its "schema" is not `schema`.
inline nlohmann::json ParseVersioned(const std::string& text, const std::string& subject, const std::string& schema) {
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw Error("catalog", subject, std::string("not valid JSON: ") + e.what());
  }
  if (!doc.is_object()) throw Error("catalog", subject, "is not a JSON object");
  const auto it = doc.find("schema");
  const std::string found = it != doc.end() && it->is_string() ? it->get<std::string>() : std::string();
  if (found != schema) throw Error("catalog", subject, "schema is '" + found + "', expected '" + schema + "'");
  return doc;
}

// A whole number that fits an int, from a JSON value: refuses a fraction, a
// non-number or an out-of-range value (1e126 would be undefined behaviour to
// convert) with Error("catalog", subject + ": " + field, ...).
inline int JsonInt(const nlohmann::json& j, const std::string& subject, const std::string& field) {
  const bool integral = j.is_number_integer() ||
                        (j.is_number_float() && std::isfinite(j.get<double>()) && j.get<double>() == std::floor(j.get<double>()));
  if (!integral) throw Error("catalog", subject + ": " + field, "must be a whole number, got " + j.dump());
  const double v = j.is_number_unsigned() ? static_cast<double>(j.get<std::uint64_t>()) : j.get<double>();
  if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) {
    throw Error("catalog", subject + ": " + field, "is out of range, got " + j.dump());
  }
  return static_cast<int>(v);
}

}  // namespace skyfall::catalogs
