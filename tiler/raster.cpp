#include "tiler/raster.h"

#include <vector>

#include "core/error.h"
#include "tiler/gdal_util.h"

namespace skyfall {

RasterInfo ReadRasterInfo(const std::string& path) {
  gdal::Dataset ds(gdal::OpenOrThrow(path));
  RasterInfo info;
  info.path = path;
  info.driver = GDALGetDriverShortName(GDALGetDatasetDriver(ds.handle));
  info.width_px = GDALGetRasterXSize(ds.handle);
  info.height_px = GDALGetRasterYSize(ds.handle);
  info.bands = GDALGetRasterCount(ds.handle);
  if (info.bands < 1) throw Error("raster", path, "has no bands");
  if (info.width_px < 1 || info.height_px < 1) throw Error("raster", path, "has an empty pixel grid");
  info.dtype = GDALGetDataTypeName(GDALGetRasterDataType(GDALGetRasterBand(ds.handle, 1)));
  info.metadata = gdal::MetadataMap(ds.handle, "");
  info.rpc_metadata = gdal::MetadataMap(ds.handle, "RPC");
  return info;
}

void VerifyRasterPixels(const std::string& path) {
  gdal::Dataset ds(gdal::OpenOrThrow(path));
  const int width = GDALGetRasterXSize(ds.handle), height = GDALGetRasterYSize(ds.handle);
  const int bands = GDALGetRasterCount(ds.handle);
  constexpr int kRowsPerRead = 64;
  std::vector<double> buffer(static_cast<size_t>(width) * kRowsPerRead);
  gdal::QuietErrors quiet;
  for (int b = 1; b <= bands; ++b) {
    GDALRasterBandH band = GDALGetRasterBand(ds.handle, b);
    for (int row = 0; row < height; row += kRowsPerRead) {
      const int rows = std::min(kRowsPerRead, height - row);
      if (GDALRasterIO(band, GF_Read, 0, row, width, rows, buffer.data(), width, rows, GDT_Float64,
                       0, 0) != CE_None) {
        throw Error("raster", path,
                    "pixel data unreadable in band " + std::to_string(b) + " near row " +
                        std::to_string(row) + " (truncated or corrupt): " + quiet.LastMessage());
      }
    }
  }
}

FloatBand ReadFloatBand(const std::string& path, int band_index) {
  gdal::Dataset ds(gdal::OpenOrThrow(path));
  if (band_index < 1 || band_index > GDALGetRasterCount(ds.handle)) {
    throw Error("raster", path, "has no band " + std::to_string(band_index));
  }
  GDALRasterBandH band = GDALGetRasterBand(ds.handle, band_index);
  FloatBand out;
  out.width_px = GDALGetRasterXSize(ds.handle);
  out.height_px = GDALGetRasterYSize(ds.handle);
  out.values.resize(static_cast<size_t>(out.width_px) * out.height_px);
  int has_nodata = 0;
  out.nodata = GDALGetRasterNoDataValue(band, &has_nodata);
  out.has_nodata = has_nodata != 0;
  gdal::QuietErrors quiet;
  if (GDALRasterIO(band, GF_Read, 0, 0, out.width_px, out.height_px, out.values.data(),
                   out.width_px, out.height_px, GDT_Float32, 0, 0) != CE_None) {
    throw Error("raster", path, "pixel data unreadable (truncated or corrupt): " + quiet.LastMessage());
  }
  return out;
}

}  // namespace skyfall
