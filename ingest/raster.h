// Raster access through GDAL. The public interface speaks std types only.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/dsm_grid.h"

namespace skyfall {

struct RasterInfo {
  std::string path;
  std::string driver;      // GDAL driver short name ("GTiff", "NITF")
  int width_px = 0;
  int height_px = 0;
  int bands = 0;
  std::string dtype;       // GDAL data type name of band 1 ("Byte", "Float32")
  std::map<std::string, std::string> metadata;      // default domain
  std::map<std::string, std::string> rpc_metadata;  // "RPC" domain; empty when none
  // "IMAGERY" domain: what GDAL's metadata readers found in the vendor's
  // files (e.g. ACQUISITIONDATETIME of DigitalGlobe, Pleiades, SPOT).
  std::map<std::string, std::string> imagery_metadata;
};

// Opens the raster and reads its description. Throws Error("raster", path, ...)
// with GDAL's own message when the file is missing or not a readable raster.
RasterInfo ReadRasterInfo(const std::string& path);

// The georeferencing of a north-up raster with square pixels: the
// upper-left corner and pixel size in CRS units, and the CRS's EPSG code (0
// when it has none). Throws Error naming the file when it has no
// geotransform or is rotated or sheared.
struct GeoGrid {
  double upper_left_x = 0, upper_left_y = 0, pixel_size = 0;
  int width_px = 0, height_px = 0;
  int epsg = 0;
};
GeoGrid ReadGeoGrid(const std::string& path);

// Reads every pixel of every band once, so that truncated or corrupt files are
// caught at ingestion rather than halfway through a tile run. Throws Error
// naming the band and row where reading failed.
void VerifyRasterPixels(const std::string& path);

// A single band as float, row-major, with its size.
struct FloatBand {
  int width_px = 0;
  int height_px = 0;
  std::vector<float> values;
  bool has_nodata = false;
  double nodata = 0.0;
};
FloatBand ReadFloatBand(const std::string& path, int band = 1);

// All bands as float, interleaved by pixel (bands values per pixel), row-major.
struct FloatImage {
  int width_px = 0;
  int height_px = 0;
  int bands = 0;
  std::vector<float> values;
};
FloatImage ReadFloatImage(const std::string& path);

// Writing GeoTIFFs (DEFLATE, tiled when large). The file appears atomically:
// GDAL writes a temporary file beside `path`, which is renamed when complete.
struct RasterWriteOptions {
  std::map<std::string, std::string> metadata;      // default-domain items (e.g. NITF_IDATIM)
  std::map<std::string, std::string> rpc_metadata;  // RPC domain (GDAL keys), written as the GeoTIFF RPC tag
};
// `pixels` is band-interleaved by pixel: bands values per pixel, row-major.
void WriteByteTiff(const std::string& path, int width_px, int height_px, int bands,
                   const std::uint8_t* pixels, const RasterWriteOptions& options = {});
void WriteUInt16Tiff(const std::string& path, int width_px, int height_px, int bands,
                     const std::uint16_t* pixels, const RasterWriteOptions& options = {});
void WriteFloatTiff(const std::string& path, int width_px, int height_px, const float* pixels,
                    const RasterWriteOptions& options = {});
// A float32 GeoTIFF in the COG layout (tiled 256, DEFLATE, overviews) with
// NaN nodata, on a north-up grid with square pixels; written atomically.
struct NorthUpGrid {
  double upper_left_x = 0;  // CRS units (UTM metres)
  double upper_left_y = 0;
  double pixel_size = 1;
  int epsg = 0;
  // Heights: what they are measured from, stated by the CRS (3D or
  // compound) and the HEIGHT_REFERENCE metadata item. Unset: not heights.
  std::optional<HeightReference> heights;
};
void WriteFloatCog(const std::string& path, int width_px, int height_px, const float* pixels,
                   const NorthUpGrid& grid);

// A multi-band COG: pixels interleaved by pixel, row-major, of one sample
// type. Float bands have NaN nodata; with `last_is_alpha` the last band is
// an alpha band (0 = nothing there), as GIS viewers expect of an RGBA or
// grey-alpha image.
enum class SampleType { kByte, kUInt16, kFloat32 };
struct CogBands {
  int count = 1;
  std::vector<std::string> descriptions;         // one per band (GDAL band description), or none
  bool last_is_alpha = false;
  bool colour = false;                            // the first three bands are red, green, blue
  std::map<std::string, std::string> metadata;   // default-domain items
  // A class raster (one Byte band): its nodata code and a colour per code
  // for GIS viewers; its overviews then take the nearest code, never a mean.
  std::optional<int> byte_nodata;
  std::map<int, std::array<std::uint8_t, 3>> colour_table;
};
void WriteCog(const std::string& path, int width_px, int height_px, SampleType type, const void* pixels,
              const NorthUpGrid& grid, const CogBands& bands);
// PNG compression: zlib's default level, or its fastest (level 1: about
// 3x faster to write, files slightly larger) for working images written by
// the hundred, such as the synthesis stage's renders.
enum class PngCompression { kDefault, kFast };
// An 8-bit PNG (1 or 3 bands, interleaved by pixel), written atomically.
void WriteBytePng(const std::string& path, int width_px, int height_px, int bands, const std::uint8_t* pixels,
                  PngCompression compression = PngCompression::kDefault);
// The same from values in [0, 1] (clamped, rounded to 8 bits), `bands` per pixel.
void WriteUnitPng(const std::string& path, int width_px, int height_px, int bands, const std::vector<float>& values,
                  PngCompression compression = PngCompression::kDefault);

}  // namespace skyfall
