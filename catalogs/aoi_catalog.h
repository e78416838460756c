// aoi.json: the per-AOI input catalog written by `skyfall ingest` and read by
// every later stage. Versioned by its "schema" field.
#pragma once

#include <string>

#include "core/aoi.h"

namespace skyfall {

inline constexpr const char* kAoiCatalogSchema = "skyfall.aoi/1";

std::string AoiCatalogToJson(const AoiCatalog& catalog);
// Throws Error("catalog", subject, ...) naming the missing or bad field.
AoiCatalog AoiCatalogFromJson(const std::string& text, const std::string& subject);

// An image's radiometry as JSON (also in cameras.json), and back; throws
// Error("catalog", subject, ...) for a malformed one.
std::string RadiometryJson(const Radiometry& radiometry);
Radiometry RadiometryFromJson(const std::string& text, const std::string& subject);

// Atomic write (see core/atomic_file.h) and read.
void WriteAoiCatalog(const std::string& path, const AoiCatalog& catalog);
AoiCatalog ReadAoiCatalog(const std::string& path);

}  // namespace skyfall
