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
#include "products/dsm_breakdown.h"
#include "ingest/dfc2019.h"

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

struct DsmCompareOptions {
  int max_shift_px = 5;        // search radius per pyramid level
  int pyramid_levels = 2;      // 2x levels searched coarse to fine
  bool mask_water = true;      // CLS == 9 is left out
  double within_m = 1.0;       // threshold of the "within" fraction
  DsmBreakdownOptions breakdown;  // error by class and beside building outlines (needs classes)
  void Check() const;          // throws Error("dsm", field, ...)
};

struct DsmComparison {
  int shift_col_px = 0;   // prediction sampled at (col + shift_col, row + shift_row)
  int shift_row_px = 0;
  double ncc = 0;         // normalized cross-correlation at the shift
  double bias_m = 0;      // mean (pred - truth) after the shift, before z_offset_m is removed
  double z_offset_m = 0;  // median (pred - truth): the vertical offset removed before the metrics
  double mae_m = 0, rmse_m = 0, median_abs_m = 0, nmad_m = 0;
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
