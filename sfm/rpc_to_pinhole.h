// Approximating an RPC camera by a pinhole camera in a local ENU frame (as
// VisSat / SatelliteSfM do): a DLT over a dense 3D grid of RPC
// correspondences covering the image and the scene's height range, an RQ
// decomposition into K[R|t], then Levenberg-Marquardt on the reprojection
// error. The error against the RPC is measured on a separate, offset grid.
#pragma once

#include <functional>

#include "core/aoi.h"
#include "core/height.h"
#include "core/option_range.h"
#include "core/pinhole.h"
#include "core/rpc.h"

namespace skyfall {

struct PinholeFitOptions {
  int grid_cols = 15;     // image-space fit grid (edges included)
  int grid_rows = 15;
  int grid_heights = 7;   // heights across the range
  int check_cols = 24;    // check grid: cell centres of a finer grid
  int check_rows = 24;
  int check_heights = 6;
  // Hartley normalization of both point sets before the DLT. Without it the
  // DLT system (coordinates ~1e2 m against pixels ~1e3 and a camera 6e5 m
  // away) loses most of its digits; kept as an option so a test can show it.
  bool hartley_normalization = true;
  bool refine = true;         // nonlinear least squares after the DLT
  bool estimate_skew = true;  // free K(0,1) during refinement
  void Check() const;         // throws Error("pinhole", field, ...)
};
template <class IO> void Visit(IO& io, PinholeFitOptions& o) {
  io("grid_cols", o.grid_cols,
     "Columns of the image-space grid of RPC correspondences the pinhole camera is fitted to (edges included)",
     range::AtLeast(3));
  io("grid_rows", o.grid_rows,
     "Rows of the fit grid (edges included)", range::AtLeast(3));
  io("grid_heights", o.grid_heights,
     "Heights of the fit grid, spread across the height range", range::AtLeast(2));
  io("check_cols", o.check_cols,
     "Columns of the check grid (the cell centres of a finer grid) on which the fit's error against the RPC is "
     "measured", range::AtLeast(1));
  io("check_rows", o.check_rows,
     "Rows of the check grid", range::AtLeast(1));
  io("check_heights", o.check_heights,
     "Heights of the check grid", range::AtLeast(1));
  io("hartley_normalization", o.hartley_normalization,
     "Normalize both point sets (Hartley) before the DLT; without it the DLT loses most of its precision");
  io("refine", o.refine,
     "Refine the DLT's camera by nonlinear least squares");
  io("estimate_skew", o.estimate_skew,
     "Let the skew K(0,1) vary during the refinement");
}

struct PinholeFit {
  PinholeCamera camera;
  double dlt_max_error_px = 0.0;  // DLT alone, on the check grid
  double dlt_mean_error_px = 0.0;
  double max_error_px = 0.0;      // final camera vs the RPC, on the check grid
  double mean_error_px = 0.0;
};

// `enu_from_geodetic` maps (lon, lat, height) into the local frame the camera
// lives in (the AOI's ENU frame). The RPC is sampled between the two
// ellipsoidal heights (its own height frame).
PinholeFit ApproximateRpcByPinhole(
    const RpcModel& rpc, int width_px, int height_px, EllipsoidHeightM min_height, EllipsoidHeightM max_height,
    const std::function<Eigen::Vector3d(const GeodeticPoint&)>& enu_from_geodetic,
    const PinholeFitOptions& options = {});

}  // namespace skyfall
