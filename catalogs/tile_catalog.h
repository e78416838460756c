// tile.json (one tile's spec) and tiles.json (the index of a city's tiles).
#pragma once

#include <string>

#include "core/tile.h"

namespace skyfall {

inline constexpr const char* kTileSchema = "skyfall.tile/1";

std::string TileSpecToJson(const TileSpec& tile);
// Throws Error("catalog", subject, ...) naming the missing or bad field.
TileSpec TileSpecFromJson(const std::string& text, const std::string& subject);
TileSpec ReadTileSpec(const std::string& path);

}  // namespace skyfall
