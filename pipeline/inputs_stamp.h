// What a rerun compares to tell what changed since the last run: per image
// its path, size, modification time and the SHA-256 of its RPC model; per
// truth file its path, size, time and content hash; and the hash of the
// options that affect results (everything but the executor section). An
// unchanged city is not recomputed; a tile whose images changed is redone.
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/aoi.h"
#include "pipeline/run_options.h"

namespace skyfall {

// Per image source path: its stamp {path, size_bytes, mtime_ns, rpc_sha256}.
// Throws Error naming the file when an image cannot be read.
std::map<std::string, nlohmann::json> ImageStamps(const std::vector<AoiCatalog>& aois);

// The whole city's inputs: {schema, aois: [{aoi, images: [...], truth}], options_sha256}.
nlohmann::json CityInputsStamp(const RunOptions& options, const std::vector<AoiCatalog>& aois,
                               const std::map<std::string, nlohmann::json>& image_stamps);

// A tile's inputs: the stamps of the images it reads ({images: [...]}).
nlohmann::json TileInputsStamp(const std::string& tile_dir, const std::map<std::string, nlohmann::json>& image_stamps);

// Compares a tile's inputs with those recorded in tile_dir/inputs.json. When
// they differ (or none were recorded while products exist), the tile's
// products of the earlier inputs are removed so every stage runs again; then
// the new stamp is recorded. Returns true when the tile was reset.
bool ResetTileIfInputsChanged(const std::string& tile_dir, const nlohmann::json& stamp);

// The SHA-256 of the options that affect results.
std::string ResultOptionsSha256(const RunOptions& options);

}  // namespace skyfall
