// Fitting an RPC00B model to any camera's ground-to-image function, as the
// satellite vendors do for their physical sensor models: sample a 3D grid of
// (lon, lat, height) over the scene, solve for the cubic rational polynomial
// by linear least squares, and report the residual on a denser, offset
// check grid.
#pragma once

#include <Eigen/Core>
#include <functional>

#include "core/rpc.h"

namespace skyfall {

struct RpcFitOptions {
  int fit_steps_lonlat = 15;    // fit grid samples per horizontal axis
  int fit_steps_height = 9;     // fit grid samples along height
  int check_steps_lonlat = 24;  // check grid samples per horizontal axis (between fit samples)
  int check_steps_height = 8;   // check grid samples along height
  int rational_iterations = 3;  // reweighted rational refinements after the polynomial fit
  // Tikhonov weight on the denominator terms, relative to the data scale;
  // keeps the rational refinement away from near-common factors.
  double denominator_ridge = 1e-8;
  void Check() const;  // throws Error("rpc_fit", field, ...)
};

struct RpcFitDomain {
  double min_lon_deg, max_lon_deg;
  double min_lat_deg, max_lat_deg;
  double min_height_m, max_height_m;
};

struct RpcFitResult {
  RpcModel rpc;
  double max_residual_px = 0.0;  // over the check grid
  double rms_residual_px = 0.0;
  bool rational = false;         // whether the rational refinement was kept
};

// `project` maps (lon_deg, lat_deg, height_m) to (col, row) in the RPC00B
// pixel convention. Throws Error if the domain is empty or the fit fails.
RpcFitResult FitRpc(const std::function<Eigen::Vector2d(double, double, double)>& project,
                    const RpcFitDomain& domain, const RpcFitOptions& options = {});

}  // namespace skyfall
