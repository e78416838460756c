#include "ingest/raster.h"

#include <ogr_srs_api.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <vector>

#include "core/error.h"
#include "ingest/gdal_util.h"
#include "ingest/vertical_datum.h"

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
  info.imagery_metadata = gdal::MetadataMap(ds.handle, "IMAGERY");
  return info;
}

GeoGrid ReadGeoGrid(const std::string& path) {
  gdal::Dataset ds(gdal::OpenOrThrow(path));
  double gt[6];
  if (GDALGetGeoTransform(ds.handle, gt) != CE_None) throw Error("raster", path, "has no georeferencing (geotransform)");
  if (gt[2] != 0 || gt[4] != 0 || !(gt[1] > 0) || std::abs(gt[5] + gt[1]) > 1e-9 * gt[1]) {
    throw Error("raster", path, "is not a north-up grid with square pixels (geotransform " + std::to_string(gt[1]) +
                                    ", " + std::to_string(gt[2]) + ", " + std::to_string(gt[4]) + ", " +
                                    std::to_string(gt[5]) + ")");
  }
  GeoGrid g;
  g.upper_left_x = gt[0];
  g.upper_left_y = gt[3];
  g.pixel_size = gt[1];
  g.width_px = GDALGetRasterXSize(ds.handle);
  g.height_px = GDALGetRasterYSize(ds.handle);
  OGRSpatialReferenceH srs = GDALGetSpatialRef(ds.handle);
  if (srs) {
    OSRAutoIdentifyEPSG(srs);
    // A compound CRS (UTM + EGM96 height) has its zone's code on the PROJCS node.
    const char* code = OSRGetAuthorityCode(srs, OSRIsCompound(srs) ? "PROJCS" : nullptr);
    if (code) g.epsg = std::atoi(code);
  }
  return g;
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

// Every raster writer: the pixels go into a MEM dataset, `prepare` adds
// georeferencing or metadata, and `driver` writes it to a temporary file
// beside `path` that is renamed into place once complete.
void WriteThroughMem(const std::string& path, const char* driver, int width_px, int height_px, int bands,
                     GDALDataType type, const void* pixels, const std::function<void(GDALDatasetH)>& prepare,
                     const std::vector<const char*>& create_options) {
  gdal::EnsureRegistered();
  if (width_px < 1 || height_px < 1 || bands < 1) throw Error("raster", path, "refusing to write an empty raster");
  gdal::QuietErrors quiet;
  GDALDatasetH mem = GDALCreate(GDALGetDriverByName("MEM"), "", width_px, height_px, bands, type, nullptr);
  if (!mem) throw Error("raster", path, "cannot allocate the image: " + quiet.LastMessage());
  const int type_bytes = GDALGetDataTypeSizeBytes(type);
  if (GDALDatasetRasterIO(mem, GF_Write, 0, 0, width_px, height_px, const_cast<void*>(pixels), width_px, height_px,
                          type, bands, nullptr, static_cast<GSpacing>(type_bytes) * bands,
                          static_cast<GSpacing>(type_bytes) * bands * width_px, type_bytes) != CE_None) {
    GDALClose(mem);
    throw Error("raster", path, "cannot copy the pixels into the image: " + quiet.LastMessage());
  }
  if (prepare) prepare(mem);
  const std::string tmp = path + ".tmp" + std::filesystem::path(path).extension().string();
  std::error_code ec;
  const auto parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  std::vector<const char*> options = create_options;
  options.push_back(nullptr);
  GDALDatasetH out = GDALCreateCopy(GDALGetDriverByName(driver), tmp.c_str(), mem, FALSE,
                                    const_cast<char**>(options.data()), nullptr, nullptr);
  GDALClose(mem);
  if (!out) {
    std::filesystem::remove(tmp, ec);
    throw Error("raster", path, std::string(driver) + " write failed: " + quiet.LastMessage());
  }
  GDALClose(out);
  if (CPLGetLastErrorType() == CE_Failure) {
    std::filesystem::remove(tmp, ec);
    throw Error("raster", path, "write failed: " + quiet.LastMessage());
  }
  std::filesystem::remove(tmp + ".aux.xml", ec);  // PAM side file of the temporary name
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw Error("raster", path, "rename failed: " + ec.message());
}

void WriteTiff(const std::string& path, int width_px, int height_px, int bands, GDALDataType type,
               const void* pixels, const RasterWriteOptions& options) {
  const bool tiled = width_px > 512 || height_px > 512;
  WriteThroughMem(
      path, "GTiff", width_px, height_px, bands, type, pixels,
      [&](GDALDatasetH ds) {
        for (const auto& [k, v] : options.metadata) GDALSetMetadataItem(ds, k.c_str(), v.c_str(), nullptr);
        for (const auto& [k, v] : options.rpc_metadata) GDALSetMetadataItem(ds, k.c_str(), v.c_str(), "RPC");
      },
      {"COMPRESS=DEFLATE", tiled ? "TILED=YES" : "TILED=NO", bands > 1 ? "INTERLEAVE=PIXEL" : "INTERLEAVE=BAND"});
}

}  // namespace

void WriteByteTiff(const std::string& path, int width_px, int height_px, int bands,
                   const std::uint8_t* pixels, const RasterWriteOptions& options) {
  WriteTiff(path, width_px, height_px, bands, GDT_Byte, pixels, options);
}

void WriteUInt16Tiff(const std::string& path, int width_px, int height_px, int bands,
                     const std::uint16_t* pixels, const RasterWriteOptions& options) {
  WriteTiff(path, width_px, height_px, bands, GDT_UInt16, pixels, options);
}

void WriteBytePng(const std::string& path, int width_px, int height_px, int bands, const std::uint8_t* pixels,
                  PngCompression compression) {
  std::vector<const char*> options;
  if (compression == PngCompression::kFast) options.push_back("ZLEVEL=1");
  WriteThroughMem(path, "PNG", width_px, height_px, bands, GDT_Byte, pixels, nullptr, options);
}

void WriteUnitPng(const std::string& path, int width_px, int height_px, int bands, const std::vector<float>& values,
                  PngCompression compression) {
  std::vector<std::uint8_t> bytes(values.size());
  for (std::size_t k = 0; k < bytes.size(); ++k)
    bytes[k] = std::isfinite(values[k])  // NaN (a broken render) as black, not undefined
                   ? static_cast<std::uint8_t>(std::clamp(values[k], 0.0f, 1.0f) * 255.0f + 0.5f)
                   : 0;
  WriteBytePng(path, width_px, height_px, bands, bytes.data(), compression);
}

namespace {

// A paletted band: every code without an entry is black and transparent.
void SetColourTable(GDALRasterBandH band, const std::map<int, std::array<std::uint8_t, 3>>& colours) {
  GDALColorTableH table = GDALCreateColorTable(GPI_RGB);
  for (int code = 0; code < 256; ++code) {
    const auto it = colours.find(code);
    GDALColorEntry entry{0, 0, 0, 0};
    if (it != colours.end()) entry = {it->second[0], it->second[1], it->second[2], 255};
    GDALSetColorEntry(table, code, &entry);
  }
  GDALSetRasterColorTable(band, table);
  GDALDestroyColorTable(table);
}

}  // namespace

void WriteCog(const std::string& path, int width_px, int height_px, SampleType type, const void* pixels,
              const NorthUpGrid& grid, const CogBands& bands) {
  const GDALDataType gdal_type = type == SampleType::kByte     ? GDT_Byte
                                 : type == SampleType::kUInt16 ? GDT_UInt16
                                                               : GDT_Float32;
  WriteThroughMem(
      path, "COG", width_px, height_px, bands.count, gdal_type, pixels,
      [&](GDALDatasetH ds) {
        double gt[6] = {grid.upper_left_x, grid.pixel_size, 0, grid.upper_left_y, 0, -grid.pixel_size};
        GDALSetGeoTransform(ds, gt);
        GDALSetProjection(ds, GeoTiffCrsWkt(grid.epsg, grid.heights).c_str());
        if (grid.heights) {
          GDALSetMetadataItem(ds, kHeightReferenceItem, EnumName(*grid.heights), nullptr);
          GDALRasterBandH band = GDALGetRasterBand(ds, 1);
          GDALSetRasterUnitType(band, "m");
          if (bands.descriptions.empty())
            GDALSetDescription(band, ("height above the " + HeightReferenceDescription(*grid.heights)).c_str());
        }
        for (const auto& [key, value] : bands.metadata) GDALSetMetadataItem(ds, key.c_str(), value.c_str(), nullptr);
        for (int b = 0; b < bands.count; ++b) {
          GDALRasterBandH band = GDALGetRasterBand(ds, b + 1);
          if (b < static_cast<int>(bands.descriptions.size()))
            GDALSetDescription(band, bands.descriptions[b].c_str());
          if (type == SampleType::kFloat32) GDALSetRasterNoDataValue(band, std::numeric_limits<double>::quiet_NaN());
          if (bands.colour && b < 3) GDALSetRasterColorInterpretation(band, static_cast<GDALColorInterp>(GCI_RedBand + b));
          if (bands.last_is_alpha && b == bands.count - 1) GDALSetRasterColorInterpretation(band, GCI_AlphaBand);
          if (bands.byte_nodata) GDALSetRasterNoDataValue(band, *bands.byte_nodata);
        }
        if (!bands.colour_table.empty()) SetColourTable(GDALGetRasterBand(ds, 1), bands.colour_table);
      },
      bands.colour_table.empty()
          ? std::vector<const char*>{"COMPRESS=DEFLATE", "BLOCKSIZE=256", "OVERVIEWS=AUTO", "GEOTIFF_VERSION=1.1"}
          : std::vector<const char*>{"COMPRESS=DEFLATE", "BLOCKSIZE=256", "OVERVIEWS=AUTO", "GEOTIFF_VERSION=1.1",
                                     "RESAMPLING=NEAREST"});
}

void WriteFloatCog(const std::string& path, int width_px, int height_px, const float* pixels,
                   const NorthUpGrid& grid) {
  WriteCog(path, width_px, height_px, SampleType::kFloat32, pixels, grid, CogBands{});
}

void WriteFloatTiff(const std::string& path, int width_px, int height_px, const float* pixels,
                    const RasterWriteOptions& options) {
  WriteTiff(path, width_px, height_px, 1, GDT_Float32, pixels, options);
}

}  // namespace skyfall
