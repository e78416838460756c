// A synthetic but realistic RPC00B model (WorldView-3-like magnitudes: a
// near-affine camera with small second and third order terms) for unit tests
// that must not depend on external data.
#pragma once

#include "core/rpc.h"

namespace skyfall::testing {

inline RpcModel MakeTestRpc() {
  RpcModel rpc;
  rpc.line_off = 8155.4;
  rpc.samp_off = -15391.6;
  rpc.lat_off = 30.2992;
  rpc.lon_off = -81.6397;
  rpc.height_off = -21.0;
  rpc.line_scale = 19234.0;
  rpc.samp_scale = 21250.0;
  rpc.lat_scale = 0.0686;
  rpc.lon_scale = 0.0698;
  rpc.height_scale = 501.0;
  rpc.line_num = {-0.0018, 1.0589, -0.0487, -0.0089, 0.00094, 0.00032, -2.96e-05,
                  0.000905, 2.15e-06, -1.97e-06, -2.2e-06, -0.000328, -7.33e-05, -9.28e-05,
                  9.5e-05, 3.25e-06, 4.27e-06, 2.19e-06, 6.59e-07, 7.84e-07};
  rpc.line_den = {1.0, 0.00083, -0.00108, -0.000357, -7.9e-05, -4.39e-06, -2.1e-06,
                  0.00021, -5.7e-05, -8.78e-05, 1.26e-06, 0.000698, 2.8e-06, 9.85e-08,
                  -8.4e-05, 1.1e-07, 1.76e-07, -1.72e-05, 2.85e-08, 5.85e-08};
  rpc.samp_num = {-0.0068, 0.00105, 1.0315, 0.0021, -0.0004, 0.0011, 3.1e-05,
                  -0.00021, 4.4e-06, 1.2e-06, -3.3e-06, 2.2e-05, -0.00061, 8.1e-06,
                  -1.4e-05, 2.9e-06, -5.5e-07, 1.1e-06, -2.4e-07, 3.3e-08};
  rpc.samp_den = {1.0, 0.00333, 0.0011, -0.000477, -5.9e-05, 2.8e-06, -2.38e-06,
                  4.28e-05, -9.7e-07, -1.12e-05, -1.46e-07, -4.37e-06, -1.3e-06, -6.07e-08,
                  3.63e-06, 4.18e-08, 4.71e-08, 4.17e-07, 0.0, 0.0};
  return rpc;
}

}  // namespace skyfall::testing
