// Where a DSM's error comes from: the error of a comparison broken down by
// the truth's classes (the ASPRS codes of DFC2019's _CLS rasters) and by
// distance from building outlines. At a building's rim one pixel of
// misplaced edge costs the building's whole height, so next to tall
// buildings a few rim cells can outweigh all the ground.
#pragma once

#include <string>
#include <vector>

#include "core/option_range.h"

namespace skyfall {

struct DsmErrorGroup {
  // "ground", "building", "class_64", "roof_rim", "beside_buildings",
  // "roof_band_<k>", "beside_band_<k>", "roof_interior"
  std::string name;
  int cls = -1;            // ASPRS class code; -1 for the rim and edge bands
  int cells = 0;           // compared cells in the group
  double share = 0;        // cells / all compared cells
  double mae_m = 0, rmse_m = 0, median_abs_m = 0;
  double bias_m = 0;       // mean signed error (pred - truth, after the comparison's vertical offset)
  // Sum of |error| over the group divided by all compared cells: the part of
  // the overall MAE the group accounts for (the classes' parts add up to it).
  double mae_part_m = 0;
};

struct DsmBreakdownOptions {
  // Building cells whose centre is within this distance of a non-building
  // cell's centre form the roof rim; non-building cells as close to a
  // building cell form the band beside buildings. 1 m: two cells at the
  // DFC2019 GSD of 0.5 m.
  double rim_width_m = 1.0;
  // The edge profile: the error in bands of edge_band_m by distance from
  // the outline, edge_bands of them on the roof side and as many beside the
  // buildings. A roof eroded by a cell shows as a low mean error in the
  // first roof bands, one fattened onto the ground as a high one beside.
  double edge_band_m = 0.5;
  int edge_bands = 6;
  int building_class = 6;  // ASPRS "building"
  // ASPRS "high vegetation": the class that published "vegetation masked"
  // figures on DFC2019 (EOGS, HLC-GS) leave out; reported apart as
  // DsmBreakdown::without_high_vegetation.
  int high_vegetation_class = 5;
  void Check() const;      // throws Error("dsm", field, ...)
};

// As the run lists them (dsm.compare.* in run_config.json).
template <class IO> void Visit(IO& io, DsmBreakdownOptions& b) {
  io.NotAnOption(b.building_class);  // the LiDAR classes' code (ASPRS 6), not a choice
  io.NotAnOption(b.high_vegetation_class);  // likewise (ASPRS 5)
  io("rim_width_m", b.rim_width_m,
     "With classes: width of the bands inside and outside building outlines whose error is reported apart",
     range::Above(0));
  io("edge_band_m", b.edge_band_m,
     "With classes: width of each band of the edge profile", range::Above(0));
  io("edge_bands", b.edge_bands,
     "With classes: bands of the edge profile on each side of the building outlines", range::In(1, 100));
}

struct DsmBreakdown {
  std::vector<DsmErrorGroup> classes;        // one per class with compared cells, ascending code
  DsmErrorGroup roof_rim, beside_buildings;  // cells = 0 when the truth has no buildings
  double rim_width_m = 0;
  // Band k (from 0) holds the cells whose centre lies more than k and at most
  // k + 1 edge_band_m from the nearest cell centre across the outline
  // ("roof_band_<k>", "beside_band_<k>"); the roof's cells beyond the last
  // band (all of them when the grid has no cell that is not building) are
  // its interior. An empty band has cells = 0 and every figure 0 (bands
  // narrower than a cell leave some empty: distances come in cell steps).
  std::vector<DsmErrorGroup> roof_bands, beside_bands;
  DsmErrorGroup roof_interior;
  double edge_band_m = 0;
  // Every compared cell but high vegetation: its mae_m is the "vegetation
  // masked" MAE of published DFC2019 figures, on this comparison's alignment
  // (shift and vertical offset found with every cell).
  DsmErrorGroup without_high_vegetation;
  // The classes, the roof rim and the band beside buildings, then every
  // cell but high vegetation: the order of the report's rows.
  std::vector<DsmErrorGroup> Groups() const;
};

// The class code of a class raster's value: -1 for NaN, nodata filled with
// NaN, or a value outside [0, 255] (ASPRS codes are bytes), so that a float
// raster from a user never reaches an undefined float-to-int conversion.
int ClassCodeOf(float value);

// The ASPRS name of a class code ("ground", "high_vegetation", ...; DFC2019's
// 65 is "unlabeled"), "no_class" for -1, else "class_<code>".
std::string AsprsClassName(int code);

// `error_m` (NaN where not compared) and `cls` are the same row-major grid of
// `width_px` x `height_px` cells of `gsd_m` metres. Throws Error on a size
// mismatch or a GSD that is not positive.
DsmBreakdown BreakDownDsmError(const std::vector<float>& error_m, const std::vector<float>& cls, int width_px,
                               int height_px, double gsd_m, const DsmBreakdownOptions& options);

}  // namespace skyfall
