// The GIS layers of an AOI beside its DSM, all on the DSM's grid: the bare
// earth (dtm.tif) and heights above it (ndsm.tif), per-cell quality layers
// (quality.tif), the true orthophoto (ortho.tif), the scene as a point
// cloud, and their comparison with the truth (DTM on ground cells, nDSM on
// buildings, the orthophoto against the input image closest to nadir).
#pragma once

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "catalogs/tile_catalog.h"
#include "core/aoi.h"
#include "core/dsm_grid.h"
#include "core/gaussians.h"
#include "core/tile.h"
#include "dense/dense_cells.h"
#include "ingest/radiometry.h"
#include "products/point_cloud.h"

namespace skyfall {

// One tile's dense cells and the spec that says which cells it owns (a
// tile without a spec owns all of its cells).
struct DenseTileCells {
  DenseCells cells;
  std::optional<TileSpec> spec;
};

// The dense stage's layers sampled at the grid's pixel centres, from the
// cell of the tile that owns each (nearest cell). NaN where no tile has a
// cell there or the tile's dense.ply predates the layer.
struct DenseLayers {
  DsmGrid dtm;                   // the terrain model, ellipsoidal heights
  std::vector<float> views;      // views of the matched pairs that see the cell
  std::vector<float> fill_rule;  // FillRule code (0 matched)
  std::vector<float> cost;       // matching cost at the cell's height
};
DenseLayers SampleDenseLayers(const std::vector<DenseTileCells>& tiles, const GeodeticPoint& enu_origin,
                              const DsmGrid& grid);

// Per pixel, the opacity-weighted vertical spread (standard deviation, m)
// of the Gaussians whose centres fall in it, each counted with its own
// vertical extent: a thin roof is centimetres, a tree or a smeared wall
// metres. NaN where no Gaussian of at least `min_opacity` is centred.
std::vector<float> GaussianHeightSpreadM(const GaussianCloud& scene, const GeodeticPoint& enu_origin,
                                         const DsmGrid& grid, double min_opacity);

// dsm - dtm, NaN where either is; reference kAboveTerrain. Both must be on
// the same grid in the same reference.
DsmGrid HeightAboveTerrain(const DsmGrid& dsm, const DsmGrid& dtm);

// quality.tif: float32 bands "views", "fill_rule", "matching_cost",
// "height_spread_m" (docs/outputs.md gives the codes).
void WriteQualityCog(const std::string& path, const DsmGrid& grid, const DenseLayers& dense,
                     const std::vector<float>& spread_m);

// ortho.tif from `rgb` (3 per pixel in [0, 1], NaN where empty): grey and
// alpha for a panchromatic scene, else red, green, blue and alpha; 8 or 16
// bits. `metadata` goes into the file (the appearance it shows).
struct OrthoFormat {
  bool grey = false;
  int bits = 8;
};
void WriteOrthoCog(const std::string& path, const DsmGrid& grid, const std::vector<float>& rgb,
                   const OrthoFormat& format, const std::map<std::string, std::string>& metadata);

// PNG previews of the products for the report page, at most kPreviewPx on
// a side: ortho.png, dsm.png (heights between their 2nd and 98th
// percentiles, dark low), views.png (dark few), fill_rule.png (one colour
// per FillRule code; black where no cell) and classes.png (classes.tif's
// colours) under `dir`. A missing layer (empty vector) writes no file.
constexpr int kPreviewPx = 768;
struct PreviewLayers {
  std::vector<float> rgb, views, fill_rule;
  std::vector<std::uint8_t> classes;  // LandCover codes
};
void WriteProductPreviews(const std::string& dir, const DsmGrid& dsm, const PreviewLayers& layers);

// DTM error on the truth's ground cells and nDSM error on its buildings.
// The truth's bare earth is the terrain model (TerrainModel) through its
// ground-class cells; its nDSM is the truth less that. The DSM comparison's
// registration (shift, vertical offset) is applied first, as to the DSM.
struct TerrainComparison {
  double dtm_mae_ground_m = NAN, dtm_bias_ground_m = NAN;
  double ndsm_mae_building_m = NAN, ndsm_bias_building_m = NAN;
  int ground_cells = 0, building_cells = 0;
};
TerrainComparison CompareTerrain(const DsmGrid& dtm, const DsmGrid& ndsm, const DsmGrid& truth,
                                 const std::vector<float>& cls, int shift_col_px, int shift_row_px,
                                 double z_offset_m);

// The orthophoto against an input image on the truth's ground cells, where
// building lean cannot differ: the image is sampled through its RPC at the
// truth's heights, both as grey levels in [0, 1], the best shift within
// `max_shift_px` kept (the RPC's own bias). SSIM over 7 x 7 windows. Ground
// the image cannot see (the truth's surface stands on the ray towards the
// satellite, at `view_zenith_deg` and `view_azimuth_deg` from north) is left
// out: there the image shows a wall or a roof.
struct OrthoAgreement {
  double psnr_db = NAN, ssim = NAN;
  int cells = 0, shift_col_px = 0, shift_row_px = 0;
};
OrthoAgreement CompareOrthoWithImage(const std::vector<float>& ortho_rgb, const DsmGrid& truth,
                                     const std::vector<float>& cls, const NormalizedImage& image, const RpcModel& rpc,
                                     double view_zenith_deg, double view_azimuth_deg, int max_shift_px = 3);

// The orthophoto in the appearance of one image's date: per band, the gain
// and offset that best map its colours to the image's (least squares) on
// the cells that image sees, placed in it through its RPC at the DSM's
// heights. The scene's colours are those of its tiles' fused appearance;
// this gives them the light and atmosphere of the chosen date. Identity
// (cells 0) with fewer than kMinColourMatchCells usable cells.
constexpr int kMinColourMatchCells = 100;
struct ColourMatch {
  std::array<double, 3> gain{1, 1, 1}, offset{0, 0, 0};
  int cells = 0;
};
ColourMatch MatchColoursToImage(const std::vector<float>& ortho_rgb, const DsmGrid& dsm, const NormalizedImage& image,
                                const RpcModel& rpc, double view_zenith_deg, double view_azimuth_deg);
// rgb := gain * rgb + offset per band, clamped to [0, 1] (NaN stays NaN).
void ApplyColourMatch(const ColourMatch& match, std::vector<float>* rgb);

// The orthophoto against an exact orthophoto on its grid (the synthetic
// city's <AOI>_ORTHO.tif, read with the nadir image's radiometry): every cell
// the truth holds, buildings included.
OrthoAgreement CompareOrthoWithTruth(const std::vector<float>& ortho_rgb, const NormalizedImage& truth,
                                     int max_shift_px = 3);

// The scene's Gaussians of at least `min_opacity` on the DTM's grid (the
// AOI) as points in its UTM zone, heights in `reference` (kEllipsoid or
// kEgm96); ground (class 2) within `ground_tolerance_m` of the DTM
// (ellipsoidal); above it, the class `land_cover` gives the point's cell
// when that is building (6) or high vegetation (5), else unclassified (1).
// Without `land_cover` (empty) every point above ground is class 1.
std::vector<LasPoint> ScenePoints(const GaussianCloud& scene, const GeodeticPoint& enu_origin, const DsmGrid& dtm,
                                  HeightReference reference, double min_opacity, double ground_tolerance_m,
                                  const std::vector<std::uint8_t>& land_cover = {});

}  // namespace skyfall
