// The products of each AOI of a finished city, on one grid per AOI (its
// truth's, else its footprint at products.gsd_m): dsm.tif, dtm.tif,
// ndsm.tif, quality.tif, ortho.tif and points.las under OUT/<AOI>/, and,
// where the AOI has a truth, their comparison with it (DSM, the dense
// heights alone, DTM on ground cells, nDSM on buildings, the orthophoto
// against the input image closest to nadir).
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/stage.h"
#include "pipeline/city_run.h"
#include "pipeline/merge_tiles.h"
#include "pipeline/run_options.h"

namespace skyfall {

// An AOI's footprint in its UTM zone: the box around its polygon.
struct UtmBox {
  Eigen::Vector2d lo, hi;
};
UtmBox FootprintUtm(const AoiCatalog& aoi);

struct AoiProducts {
  nlohmann::json comparisons = nlohmann::json::array();  // the run report's "dsm": one entry per AOI with truth
  nlohmann::json products = nlohmann::json::array();     // the run report's "products": files per AOI
  nlohmann::json city;                                   // the run report's "city_products": the mosaics
};

// Writes every AOI's products and compares those of AOIs with truth, then
// the city's mosaics (ortho_city.tif, dtm_city.tif, quality_city.tif under
// OUT/<city>/, when it has more than one AOI);
// appends a stage entry per AOI to `stages` and each DSM MAE to `outcome`.
AoiProducts WriteAoiProducts(const RunOptions& options, const std::vector<AoiCatalog>& aois,
                             const MergeSummary& merged, const std::vector<std::string>& tile_dirs,
                             const std::string& out_dir, nlohmann::json* stages, CityOutcome* outcome,
                             Progress& progress);

// products.ortho_image, when set, must name an image of one of the city's
// AOIs (an AOI without it takes its own image closest to nadir); throws
// Error naming the option otherwise.
void CheckOrthoImage(const ProductOptions& options, const std::vector<AoiCatalog>& aois);

// The files WriteAoiProducts writes for `aoi` under the options (those a
// rerun must find to skip an unchanged city).
std::vector<std::string> AoiProductFiles(const ProductOptions& options, const AoiCatalog& aoi,
                                         const std::string& out_dir);

}  // namespace skyfall
