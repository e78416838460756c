// Land cover on the DSM's grid (classes.tif, and the classes of
// points.las): ground, building and high vegetation in the ASPRS codes that
// LAS and the DFC2019 truth use. What stands more than `object_min_m` above
// the DTM is an object; an object cell is vegetation where the cells around
// it are mostly both greener than the scene's objects usually are and
// rough (not on a plane), else building. A panchromatic scene has no colour
// to tell a crown from a roof: its objects stay "above ground, not told
// apart" (code 1), and the result says so. Decision D-120.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/dsm_grid.h"
#include "core/enum_codec.h"
#include "core/option_range.h"

namespace skyfall {

// ASPRS / DFC2019 class codes, as stored in classes.tif (0 = no data).
enum class LandCover : std::uint8_t {
  kNoData = 0,
  kAboveGround = 1,  // ASPRS "unclassified": above ground, building and tree not told apart
  kGround = 2,
  kHighVegetation = 5,
  kBuilding = 6,
};

struct LandCoverOptions {
  double object_min_m = 2.0;         // a cell standing higher above the DTM is an object (building or tree)
  double green_sigmas = 2.0;         // greener than the objects' median by this many robust sigmas votes vegetation
  double min_roughness_m = 0.15;     // ... where the surface also departs this far (RMS) from a local plane
  double plane_half_window_m = 1.5;  // half side of the window of that plane fit
  double vote_radius_m = 1.0;        // half side of the window whose majority of votes decides a cell
  void Check() const;                // throws Error("products", "land_cover." field, ...)
};
template <class IO> void Visit(IO& io, LandCoverOptions& o) {
  io("object_min_m", o.object_min_m,
     "A cell standing more than this above the DTM is an object: a building or a tree", range::AboveUpTo(0, 50));
  io("green_sigmas", o.green_sigmas,
     "An object cell votes vegetation when its excess green (2g - r - b) / (r + g + b) exceeds the AOI's objects' "
     "median by this many robust sigmas (1.4826 x MAD) ...", range::In(0, 10));
  io("min_roughness_m", o.min_roughness_m,
     "... and its surface departs by more than this (RMS) from the least-squares plane around it", range::In(0, 10));
  io("plane_half_window_m", o.plane_half_window_m,
     "Half side of the window of that plane fit", range::AboveUpTo(0, 20));
  io("vote_radius_m", o.vote_radius_m,
     "Half side of the window whose majority of object cells' votes decides building or vegetation", range::In(0, 20));
}

struct LandCoverMap {
  std::vector<std::uint8_t> classes;  // LandCover codes, row-major on the DSM's grid
  bool colour = false;                // vegetation told from buildings by colour (false: panchromatic)
  double green_threshold = 0;         // excess green above which an object cell voted vegetation
  std::int64_t ground_cells = 0, building_cells = 0, vegetation_cells = 0, above_ground_cells = 0;
};

// `dsm` and `dtm` on one grid, both ellipsoidal; `rgb` 3 values per cell in
// [0, 1] (NaN where empty), or empty. `colour` false for a panchromatic
// scene (its three bands are one).
LandCoverMap ClassifyLandCover(const DsmGrid& dsm, const DsmGrid& dtm, const std::vector<float>& rgb, bool colour,
                               const LandCoverOptions& options);

// Per cell, the RMS distance (m) of the DSM from the least-squares plane
// through its finite heights within `half_window_px`; NaN with fewer than
// 4 of them. A roof face is centimetres, a crown decimetres.
std::vector<float> PlaneResidualM(const DsmGrid& dsm, int half_window_px);

// Excess green (2g - r - b) / (r + g + b) per cell; NaN where empty or black.
std::vector<float> ExcessGreen(const std::vector<float>& rgb);

// The map against the truth's classes (DFC2019 codes, on the same grid),
// with the DSM comparison's registration shift applied: predicted cell
// (col + shift_col_px, row + shift_row_px) against truth cell (col, row).
// Cells the truth leaves unlabelled (other codes) count for no class.
struct ClassAgreement {
  double iou = NAN, precision = NAN, recall = NAN;
  std::int64_t truth_cells = 0;
};
struct LandCoverAgreement {
  ClassAgreement ground, building, vegetation;
  double overall_accuracy = NAN;  // on cells the truth calls ground, building or vegetation
  std::int64_t cells = 0;
};
LandCoverAgreement CompareLandCover(const LandCoverMap& map, const std::vector<float>& truth_cls, int width_px,
                                    int height_px, int shift_col_px, int shift_row_px);

// The colour of each code in classes.tif's table and in its preview.
const std::map<int, std::array<std::uint8_t, 3>>& LandCoverColours();

// classes.tif: a Byte COG of LandCover codes, 0 nodata, with a colour table
// for GIS viewers and the codes in its CLASS_CODES item; `metadata` adds
// items (how the classes were decided).
void WriteLandCoverCog(const std::string& path, const DsmGrid& grid, const LandCoverMap& map,
                       const std::map<std::string, std::string>& metadata);

}  // namespace skyfall
