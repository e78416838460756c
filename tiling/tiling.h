// Partitioning a city (one or several adjacent AOIs) into overlapping tiles,
// each an independent unit of work with its own crop windows and RPCs.
#pragma once

#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/option_range.h"
#include "core/stage.h"
#include "core/tile.h"

namespace skyfall {

struct TilingOptions {
  // [m] side of a tile core. 0 (the default): sized by the imagery, the
  // whole multiple of kAutoTileStepM that holds closest to tile_cells cells
  // of the dense grid a side, the cell following the finest image's GSD
  // (core/ground_cell.h): 256 m for 0.3-0.6 m sensors, as fixed-size tiles
  // were; 512 m for ZY-3's 2.1 m (1 m cells), where a 256 m tile holds 120
  // px, too few to match. A value > 0 is the user's choice and is kept.
  double tile_m = 0.0;
  int tile_cells = 512;       // [cells] what an automatic tile should hold a side
  // [m] margin reconstructed around each core, and beyond the city's bounds
  // at its edge. 8 m: an inner tile
  // reconstructs 1.13x its core (1.27x at 16 m), and with the merge's seam
  // lines (merge/ownership.h) the narrower band joins tiles about as well as
  // 16 m did (decision D-065).
  double overlap_m = 8.0;
  // An image is used for a tile when at least this fraction of the tile's
  // projected 3D box (extent x height range) falls inside the image.
  double min_coverage = 0.5;
  int min_images = 2;         // below this a tile has nothing to reconstruct
  std::string city;           // name of the city; empty = the AOI name, or the AOIs' common prefix
  void Check() const;         // throws Error("tile", field, ...)
};
template <class IO> void Visit(IO& io, TilingOptions& o) {
  io("tile_m", o.tile_m,
     "Tile core side; 0: sized by the imagery (a multiple of 256 m holding about tile_cells dense cells)",
     range::Or(range::AtLeast(16), 0, "automatic"));
  io("tile_cells", o.tile_cells,
     "What an automatic tile (tile_m 0) holds along a side, in cells of the automatic dense grid (0.5 m for "
     "sub-metre sensors, else about half the finest image's GSD)", range::AtLeast(64));
  io("overlap_m", o.overlap_m,
     "Overlap margin around each tile's core", range::AtLeast(0));
  io("min_coverage", o.min_coverage,
     "An image is used for a tile when at least this fraction of the tile's 3D box (extent x height range) projects "
     "inside it", range::AboveUpTo(0, 1));
  io("min_images", o.min_images,
     "A tile seen by fewer images is kept empty and skipped", range::AtLeast(2));
  io("city", o.city,
     "Name of the city (empty = the AOI's name, or the AOIs' common prefix)");
}

// Step of automatic tile sides [m]: tiles of imagery finer than 0.75 m keep
// the 256 m side that every accuracy figure was measured with.
constexpr double kAutoTileStepM = 256.0;

// Ground sampling distance of an image at its centre [m]: the square root of
// the ground area of one pixel at `height` (ellipsoidal), from its RPC.
double ImageGroundSampleM(const ImageRecord& image, double ellipsoid_height_m);

// The tile side PlanTiles uses: options.tile_m when set, else the automatic
// side for the finest image of `aois`. `finest_gsd_m` (optional) receives
// that image's GSD.
double ChooseTileSideM(const TilingOptions& options, const std::vector<AoiCatalog>& aois,
                       double* finest_gsd_m = nullptr);

struct TilePlan {
  std::string city;
  GeodeticPoint enu_origin;   // shared by every tile
  double finest_gsd_m = 0;    // GSD of the finest image [m] (what an automatic tile side follows)
  bool tile_side_automatic = false;  // sized by tile_cells (tile_m 0), not given
  GroundBox bounds;           // union of the AOI footprints in that frame
  TileGrid grid;
  std::vector<TileSpec> tiles;         // images without crop_path yet
  std::vector<AoiCatalog> catalogs;    // per tile, what SfM reads (paths filled by WriteTiles)
  // How the tiles' bundle adjustments share one frame (AssignGaugeAcquisitions).
  std::string gauge;
  bool gauge_shared = true;  // false: the tiles' frames may differ (no two acquisitions in common)
};

// A bundle adjustment fixes its frame by the average of its images' RPCs,
// whose pointing biases (metres for vendor RPCs) differ per acquisition: tiles
// holding different acquisitions land in frames metres apart, and the city's
// DSM steps at their borders. When the tiles' acquisitions differ, every tile
// is given those that all tiles hold (two at least) to fix its frame by
// (AoiCatalog::gauge_acquisitions); `gauge` says what was chosen.
void AssignGaugeAcquisitions(TilePlan* plan);

// Plans the tiles of a city made of `aois` (adjacent AOIs ingested
// separately). Pure computation: nothing is read or written. Throws Error
// for an empty AOI list or AOIs in different UTM zones.
TilePlan PlanTiles(const TilingOptions& options, const std::vector<AoiCatalog>& aois);

// The name of a tile's folder.
std::string TileId(const std::string& city, int col, int row);

struct TilingResult {
  TilePlan plan;
  std::vector<std::string> tile_dirs;  // OUT/<tile id>, same order as plan.tiles
  StageReport report;                  // metrics: tiles, tiles_without_images, crops
};

// Writes, for each tile, OUT/<id>/tile.json, OUT/<id>/aoi.json (the tile's
// catalog: the crops with shifted RPCs) and one GDAL VRT per crop window
// (OUT/<id>/crops/<image>.vrt, a window of the source, no pixel copy), then
// OUT/tiles.json indexing them. Files whose content would not change are left
// untouched, so re-tiling never disturbs finished tile runs.
TilingResult WriteTiles(const TilePlan& plan, const std::string& out_dir, Progress& progress);

}  // namespace skyfall
