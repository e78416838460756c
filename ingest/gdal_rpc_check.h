// Cross-check of our RPC evaluation against GDAL's own RPC transformer
// (GDALCreateRPCTransformerV2, no DEM), which parses the raster's metadata
// independently. Used by tests and by `skyfall rpc check`.
#pragma once

#include <string>

#include "core/rpc.h"

namespace skyfall {

// GDAL's pixel/line puts the top-left corner of the top-left pixel at (0, 0);
// the RPC00B convention used here puts its centre there, so GDAL pixel =
// our col + this (rpc_io_test checks it on the DFC2019 crops).
inline constexpr double kGdalPixelShift = 0.5;

struct RpcAgreementOptions {
  int grid_cols = 21;        // samples across the image width (edges included)
  int grid_rows = 21;        // samples across the image height
  int grid_heights = 11;     // samples across the height range
  double min_height_m = 0;   // height range; when min >= max, the RPC validity
  double max_height_m = 0;   // range HEIGHT_OFF +- HEIGHT_SCALE is used
};

struct RpcAgreement {
  int points = 0;
  // max |our project(lon,lat,h) - GDAL's (lon,lat,h) -> pixel| [px]
  double max_project_diff_px = 0;
  // max |our project(GDAL's localization of (col,row,h)) - (col,row)| [px]
  double max_localize_diff_px = 0;
};

// Compares `ours` (the model our readers produced for the raster) with GDAL's
// transformer built from the raster's RPC metadata.
RpcAgreement CompareWithGdal(const std::string& raster_path, const RpcModel& ours, int width_px,
                             int height_px, const RpcAgreementOptions& options = {});

}  // namespace skyfall
