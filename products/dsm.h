// DSMs on UTM grids: reading/writing GeoTIFFs, rasterizing a Gaussian scene
// into a DSM with a nadir render, and the DSM comparison protocol of
// Sat-NeRF / EO-NeRF / EOGS / Skyfall-GS.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/dsm_grid.h"
#include "core/gaussians.h"
#include "core/option_range.h"
#include "core/tile.h"
#include "ingest/dfc2019.h"
#include "products/dsm_breakdown.h"
#include "splat/ply.h"

namespace skyfall {

// The truth grid of an AOI catalog, without data.
DsmGrid GridOfTruth(const TruthGrid& truth);
// The grid a DFC2019 _DSM.txt describes (lower-left corner, size, gsd), without data.
DsmGrid GridOfDsmTxt(const DsmTxt& txt, int epsg);

// Reads a DSM GeoTIFF. A raster without georeferencing (the DFC2019 truth)
// needs `grid_txt`, its _DSM.txt (lower-left convention), and `epsg`.
// A grid of `gsd_m` pixels covering [min_e, max_e] x [min_n, max_n] (UTM
// metres, upper-left corner at (min_e, max_n)); throws Error naming `subject`
// when the box is empty or the GSD not positive.
DsmGrid GridOfBounds(double min_easting_m, double min_northing_m, double max_easting_m, double max_northing_m,
                     double gsd_m, int epsg, const std::string& subject);

// `source` sampled at the pixel centres of `target` (nearest pixel, NaN
// outside `source`), so a DSM exported on any grid compares with a truth.
// Throws Error naming `source_name` when the GSDs differ.
DsmGrid SampleOnGrid(const DsmGrid& source, const DsmGrid& target, const std::string& source_name);

DsmGrid ReadDsm(const std::string& path, const std::string& grid_txt = "", int epsg = 0);

// Float32 GeoTIFF with CRS, geotransform and NaN nodata, in the COG layout
// (tiled, DEFLATE, overviews) through GDAL's COG driver; written atomically.
void WriteDsm(const std::string& path, const DsmGrid& dsm);

struct DsmExportOptions {
  double camera_height_m = 1.0e6;  // the nadir camera sits this far above: ~orthographic
  double min_alpha = 0.5;          // below this accumulated opacity a pixel is nodata
  // The height of a pixel: the depth where the accumulated opacity reaches
  // 0.5 (median, the default: faint floaters and half-covered roof edges do
  // not pull it, and its DSM error is lower; decision D-011), or
  // else the opacity-weighted expected depth.
  bool median_depth = true;
  void Check() const;  // throws Error("dsm", field, ...)
};
template <class IO> void Visit(IO& io, DsmExportOptions& o) {
  io("camera_height_m", o.camera_height_m,
     "Height of the nadir camera the DSM is rendered from (far, so nearly orthographic)", range::AtLeast(10000));
  io("min_alpha", o.min_alpha,
     "Pixels whose accumulated opacity is below this are nodata", range::Inside(0, 1));
  io("median_depth", o.median_depth,
     "A pixel's height is the depth where the accumulated opacity reaches 0.5; off: the opacity-weighted expected "
     "depth");
}

// Rasterizes the scene (in the AOI's ENU frame with origin `enu_origin`) onto
// `grid` (its data is replaced) by rendering median (or expected) depth from a nadir
// camera whose pixels are the grid's pixels, then converting each hit back
// to an ellipsoidal height. Rendered at 1e6 m the parallax of a 100 m tower
// 200 m off-centre is 2 cm.
// `rgb`, when given, receives the same render's colour (3 per pixel, in
// [0, 1], divided by the accumulated opacity: the surface's own colour),
// NaN where the DSM has no height: the true orthophoto of the scene.
void RasterizeDsm(const GaussianCloud& scene, const GeodeticPoint& enu_origin, const DsmExportOptions& options,
                  DsmGrid* grid, std::vector<float>* rgb = nullptr);

// The box in `enu_origin`'s frame (east, north) around the grid's pixel
// corners at the frame's height.
GroundBox EnuBoxOfGrid(const DsmGrid& grid, const GeodeticPoint& enu_origin);

// The Gaussians RasterizeDsm can draw on a grid of `gsd_m` pixels whose ENU
// box is `box`: those whose centre lies within three standard deviations of
// their largest axis of it (the rasterizer blends within three), plus two
// pixels of anti-aliasing and a metre of the camera's parallax. A render
// from them equals a render from the whole cloud, byte for byte.
GaussianFilter MeetsGrid(const GroundBox& box, double gsd_m);

// The Gaussians of `cloud` that `keep` takes, in order.
GaussianCloud CropCloud(const GaussianCloud& cloud, const GaussianFilter& keep);

// A grid's part: `width_px` x `height_px` pixels from (col0, row0), no data.
DsmGrid SubGrid(const DsmGrid& grid, int col0, int row0, int width_px, int height_px);
// Copies a part's per-pixel values (`channels` per pixel) into the whole's.
void PasteBlock(const std::vector<float>& part, const DsmGrid& part_grid, int col0, int row0, int channels,
                const DsmGrid& whole_grid, std::vector<float>* whole);

// A grid cut into square blocks of at most `block_px` a side, row by row.
struct GridBlock {
  int col0 = 0, row0 = 0;
  DsmGrid grid;  // no data
};
std::vector<GridBlock> GridBlocks(const DsmGrid& grid, int block_px);

// The Gaussians that meet a grid, from wherever the scene is kept (cropped
// from a cloud in memory, or read from a PLY file with the filter).
using GaussiansMeeting = std::function<GaussianCloud(const GaussianFilter& keep)>;

// RasterizeDsm block by block (GridBlocks): one camera over the whole grid,
// each block a window of its image rendered from the Gaussians that meet
// the block, so memory holds one block's Gaussians and render, not the
// scene's, and a city's mosaic needs no more than an AOI. Blocks start at
// multiples of the rasterizer's 16 px tiles, so a pixel blends the same
// Gaussians in the same order as in one render; only the float rounding of
// their image positions differs. `visit`, when given, is called with each
// block and its Gaussians after the block is rendered (for the layers that
// come from the same Gaussians).
constexpr int kDsmBlockPx = 1024;
using BlockVisitor = std::function<void(const GridBlock& block, const GaussianCloud& part)>;
void RasterizeDsmInBlocks(const GaussiansMeeting& source, const GeodeticPoint& enu_origin,
                          const DsmExportOptions& options, DsmGrid* grid, std::vector<float>* rgb = nullptr,
                          const BlockVisitor& visit = {}, int block_px = kDsmBlockPx);

struct DsmCompareOptions {
  int max_shift_px = 5;        // search radius per pyramid level
  int pyramid_levels = 2;      // 2x levels searched coarse to fine
  bool mask_water = true;      // CLS == 9 is left out
  double within_m = 1.0;       // threshold of the "within" fraction
  DsmBreakdownOptions breakdown;  // error by class and beside building outlines (needs classes)
  void Check() const;          // throws Error("dsm", field, ...)
};
template <class IO> void Visit(IO& io, DsmCompareOptions& o) {
  io("max_shift_px", o.max_shift_px,
     "Search radius of the horizontal alignment shift per pyramid level", range::AtLeast(0));
  io("pyramid_levels", o.pyramid_levels,
     "Levels of the 2x pyramid the shift is searched on, coarse to fine", range::AtLeast(1));
  io("mask_water", o.mask_water,
     "Leave water (class 9) out of the comparison");
  io("within_m", o.within_m,
     "The comparison reports the fraction of pixels whose error is at most this", range::Above(0));
  Visit(io, o.breakdown);  // the error breakdown's options, under the same keys
}

struct DsmComparison {
  int shift_col_px = 0;   // prediction sampled at (col + shift_col, row + shift_row)
  int shift_row_px = 0;
  double ncc = 0;         // normalized cross-correlation at the shift
  double bias_m = 0;      // mean (pred - truth) after the shift, before z_offset_m is removed
  double z_offset_m = 0;  // median (pred - truth): the vertical offset removed before the metrics
  double mae_m = 0, rmse_m = 0, median_abs_m = 0, nmad_m = 0;
  // The MAE with the prediction not shifted (its own median offset removed):
  // against mae_m, what the shift buys. A misregistered DSM gains much; one
  // whose errors lean to one side (ground hidden on the side away from every
  // view, filled at roof height) gains little from a shift of a pixel or two.
  double mae_at_zero_shift_m = 0;
  double completeness = 0;     // valid in both / valid in truth
  double within_fraction = 0;  // |error| <= within_m, over valid in both
  int valid_pixels = 0;
  std::vector<float> error_m;  // per truth pixel, NaN where not compared
  bool has_breakdown = false;  // the truth came with classes
  DsmBreakdown breakdown;      // error by class and beside building outlines
};

// `cls` (optional, same grid) masks water and breaks the error down by class. Both grids must have the same size.
DsmComparison CompareDsm(const DsmGrid& prediction, const DsmGrid& truth, const std::vector<float>* cls,
                         const DsmCompareOptions& options);

// A catalog's truth DSM (read through its _DSM.txt grid) and classes.
// Its heights are converted to the ellipsoid, the frame the comparison runs
// in; `stated_reference` is what the raster stated (nullopt: nothing, taken
// as ellipsoidal). A vertical CRS that cannot be converted is refused.
struct TruthDsm {
  DsmGrid dsm;
  std::vector<float> cls;  // empty when the AOI has no CLS raster
  std::optional<HeightReference> stated_reference;
};
TruthDsm ReadTruthDsm(const TruthGrid& truth);

// A class raster (_CLS.tif) for `truth`: its values, nodata as NaN. Throws
// Error naming `path` when its size is not the truth's.
std::vector<float> ReadClassRaster(const std::string& path, const DsmGrid& truth);

// Rasterizes `scene` (ENU frame at `enu_origin`) on the truth grid into
// `prediction` and compares it with the truth.
DsmComparison CompareSceneWithTruth(const GaussianCloud& scene, const GeodeticPoint& enu_origin, const TruthGrid& grid,
                                    const TruthDsm& truth, const DsmCompareOptions& options, DsmGrid* prediction,
                                    const DsmExportOptions& export_options = DsmExportOptions{});

}  // namespace skyfall
