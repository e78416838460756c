// Private helper of the catalog readers (not a public header).
#pragma once

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
  const std::string found = doc.value("schema", std::string());
  if (found != schema) throw Error("catalog", subject, "schema is '" + found + "', expected '" + schema + "'");
  return doc;
}

}  // namespace skyfall::catalogs
