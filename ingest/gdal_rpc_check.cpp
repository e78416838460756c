#include "ingest/gdal_rpc_check.h"

#include <gdal_alg.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "ingest/gdal_util.h"

namespace skyfall {

RpcAgreement CompareWithGdal(const std::string& raster_path, const RpcModel& ours, int width_px,
                             int height_px, const RpcAgreementOptions& options) {
  gdal::Dataset ds(gdal::OpenOrThrow(raster_path));
  GDALRPCInfoV2 info;
  if (!GDALExtractRPCInfoV2(GDALGetMetadata(ds.handle, "RPC"), &info)) {
    throw Error("rpc", raster_path, "GDAL finds no usable RPC metadata");
  }
  // Ask GDAL to iterate its pixel->ground inversion far below our tolerance.
  constexpr double kGdalPixelErrorThreshold = 1e-8;
  void* transformer = GDALCreateRPCTransformerV2(&info, FALSE, kGdalPixelErrorThreshold, nullptr);
  if (!transformer) throw Error("rpc", raster_path, "GDAL could not build its RPC transformer");

  double h0 = options.min_height_m, h1 = options.max_height_m;
  if (!(h0 < h1)) {
    h0 = ours.height_off - std::abs(ours.height_scale);
    h1 = ours.height_off + std::abs(ours.height_scale);
  }
  auto lerp = [](double a, double b, int i, int n) { return n < 2 ? a : a + (b - a) * i / (n - 1); };

  RpcAgreement out;
  for (int k = 0; k < options.grid_heights; ++k) {
    for (int j = 0; j < options.grid_rows; ++j) {
      for (int i = 0; i < options.grid_cols; ++i) {
        const double col = lerp(0.0, width_px - 1.0, i, options.grid_cols);
        const double row = lerp(0.0, height_px - 1.0, j, options.grid_rows);
        const double h = lerp(h0, h1, k, options.grid_heights);
        // Ground -> image at our own localization of the pixel.
        const Eigen::Vector2d ll = Localize(ours, col, row, h);
        double x = ll.x(), y = ll.y(), z = h;
        int ok = 0;
        GDALRPCTransform(transformer, TRUE, 1, &x, &y, &z, &ok);
        if (!ok) throw Error("rpc", raster_path, "GDAL failed to project a ground point");
        const Eigen::Vector2d gdal_px(x - kGdalPixelShift, y - kGdalPixelShift);
        const Eigen::Vector2d our_px = ours.Project(ll.x(), ll.y(), h);
        out.max_project_diff_px = std::max(out.max_project_diff_px, (gdal_px - our_px).norm());
        // Image -> ground by GDAL, checked in image space with our model.
        x = col + kGdalPixelShift;
        y = row + kGdalPixelShift;
        z = h;
        GDALRPCTransform(transformer, FALSE, 1, &x, &y, &z, &ok);
        if (!ok) throw Error("rpc", raster_path, "GDAL failed to localize a pixel");
        const Eigen::Vector2d back = ours.Project(x, y, h);
        out.max_localize_diff_px =
            std::max(out.max_localize_diff_px, (back - Eigen::Vector2d(col, row)).norm());
        ++out.points;
      }
    }
  }
  GDALDestroyRPCTransformer(transformer);
  return out;
}

}  // namespace skyfall
