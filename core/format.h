// Number and text formatting shared by messages, readers and text outputs.
#pragma once

#include <string>

namespace skyfall {

// Shortest text that reads back to exactly the same double ("%.17g"), so
// coordinates printed by the CLI or written to metadata lose nothing.
std::string FormatDouble(double value);

// ASCII lower case (file extensions, band names, keys compared without case).
std::string ToLower(std::string text);

// The current time as ISO 8601 UTC: "2026-11-23T18:00:00Z", or with
// milliseconds "2026-11-23T18:00:00.123Z".
std::string UtcNowIso(bool milliseconds = false);

}  // namespace skyfall
