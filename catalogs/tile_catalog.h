// tile.json (one tile's spec) and tiles.json (the index of a city's tiles).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "core/tile.h"

namespace skyfall {

inline constexpr const char* kTileSchema = "skyfall.tile/1";

// A ground box as {min_east_m, min_north_m, max_east_m, max_north_m}; the
// reader throws nlohmann::json::exception for a missing field.
nlohmann::json BoxToJson(const GroundBox& box);
GroundBox BoxFromJson(const nlohmann::json& box);

std::string TileSpecToJson(const TileSpec& tile);
// Throws Error("catalog", subject, ...) naming the missing or bad field.
TileSpec TileSpecFromJson(const std::string& text, const std::string& subject);
TileSpec ReadTileSpec(const std::string& path);

// The layout of a tile folder, read by the merge and the products.
// The Gaussians a finished tile contributes to the merge: the synthesis
// stage's scene when it ran, else the trained one.
std::string TileScenePath(const std::string& tile_dir);
// The Gaussians trained on the tile's real images alone (splat/scene.ply),
// before any synthesis stage.
std::string TileReconstructionPath(const std::string& tile_dir);
// The Gaussians the DSMs of the reconstruction come from: the training's
// surface at train.surface_at (splat/surface.ply) when it kept one, else the
// reconstruction.
std::string TileSurfacePath(const std::string& tile_dir);

}  // namespace skyfall
