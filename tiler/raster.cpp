#include "tiler/raster.h"

#include <filesystem>
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

FloatImage ReadFloatImage(const std::string& path) {
  gdal::Dataset ds(gdal::OpenOrThrow(path));
  FloatImage out;
  out.width_px = GDALGetRasterXSize(ds.handle);
  out.height_px = GDALGetRasterYSize(ds.handle);
  out.bands = GDALGetRasterCount(ds.handle);
  out.values.resize(static_cast<size_t>(out.width_px) * out.height_px * out.bands);
  gdal::QuietErrors quiet;
  const GSpacing pixel = static_cast<GSpacing>(sizeof(float)) * out.bands;
  if (GDALDatasetRasterIO(ds.handle, GF_Read, 0, 0, out.width_px, out.height_px, out.values.data(),
                          out.width_px, out.height_px, GDT_Float32, out.bands, nullptr, pixel,
                          pixel * out.width_px, sizeof(float)) != CE_None) {
    throw Error("raster", path, "pixel data unreadable (truncated or corrupt): " + quiet.LastMessage());
  }
  return out;
}

namespace {

void WriteTiff(const std::string& path, int width_px, int height_px, int bands, GDALDataType type,
               const void* pixels, const RasterWriteOptions& options) {
  gdal::EnsureRegistered();
  if (width_px < 1 || height_px < 1 || bands < 1) {
    throw Error("raster", path, "refusing to write an empty raster");
  }
  const std::string tmp = path + ".tmp.tif";
  std::error_code ec;
  const auto parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  gdal::QuietErrors quiet;
  const bool tiled = width_px > 512 || height_px > 512;
  const char* create_options[] = {"COMPRESS=DEFLATE", tiled ? "TILED=YES" : "TILED=NO",
                                  bands > 1 ? "INTERLEAVE=PIXEL" : "INTERLEAVE=BAND", nullptr};
  GDALDatasetH ds = GDALCreate(GDALGetDriverByName("GTiff"), tmp.c_str(), width_px, height_px, bands,
                               type, const_cast<char**>(create_options));
  if (!ds) throw Error("raster", path, "cannot create: " + quiet.LastMessage());
  for (const auto& [k, v] : options.metadata) GDALSetMetadataItem(ds, k.c_str(), v.c_str(), nullptr);
  for (const auto& [k, v] : options.rpc_metadata) GDALSetMetadataItem(ds, k.c_str(), v.c_str(), "RPC");
  const int type_bytes = GDALGetDataTypeSizeBytes(type);
  const CPLErr err = GDALDatasetRasterIO(
      ds, GF_Write, 0, 0, width_px, height_px, const_cast<void*>(pixels), width_px, height_px, type,
      bands, nullptr, static_cast<GSpacing>(type_bytes) * bands,
      static_cast<GSpacing>(type_bytes) * bands * width_px, type_bytes);
  GDALClose(ds);
  if (err != CE_None || CPLGetLastErrorType() == CE_Failure) {
    std::filesystem::remove(tmp, ec);
    throw Error("raster", path, "write failed: " + quiet.LastMessage());
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw Error("raster", path, "rename failed: " + ec.message());
}

}  // namespace

void WriteByteTiff(const std::string& path, int width_px, int height_px, int bands,
                   const std::uint8_t* pixels, const RasterWriteOptions& options) {
  WriteTiff(path, width_px, height_px, bands, GDT_Byte, pixels, options);
}

void WriteBytePng(const std::string& path, int width_px, int height_px, int bands, const std::uint8_t* pixels) {
  gdal::EnsureRegistered();
  gdal::QuietErrors quiet;
  GDALDatasetH mem = GDALCreate(GDALGetDriverByName("MEM"), "", width_px, height_px, bands, GDT_Byte, nullptr);
  if (!mem) throw Error("raster", path, "cannot allocate the image: " + quiet.LastMessage());
  GDALDatasetRasterIO(mem, GF_Write, 0, 0, width_px, height_px, const_cast<std::uint8_t*>(pixels), width_px,
                      height_px, GDT_Byte, bands, nullptr, bands, static_cast<GSpacing>(bands) * width_px, 1);
  const std::string tmp = path + ".tmp.png";
  std::error_code ec;
  const auto parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  GDALDatasetH png = GDALCreateCopy(GDALGetDriverByName("PNG"), tmp.c_str(), mem, FALSE, nullptr, nullptr, nullptr);
  GDALClose(mem);
  if (!png) throw Error("raster", path, "PNG write failed: " + quiet.LastMessage());
  GDALClose(png);
  std::filesystem::remove(tmp + ".aux.xml", ec);
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw Error("raster", path, "rename failed: " + ec.message());
}

void WriteFloatTiff(const std::string& path, int width_px, int height_px, const float* pixels,
                    const RasterWriteOptions& options) {
  WriteTiff(path, width_px, height_px, 1, GDT_Float32, pixels, options);
}

}  // namespace skyfall
