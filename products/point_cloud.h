// Georeferenced point clouds as LAS 1.4 (ASPRS, R15), plain, LAZ-compressed
// (products/laz_encoder.h) or as a Cloud Optimized Point Cloud (COPC 1.0,
// products/copc.h): the formats GIS and point-cloud tools read.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/enum_codec.h"

namespace skyfall {

// One point, in a projected CRS (UTM metres) with a height in the CRS's vertical frame.
struct LasPoint {
  double easting_m = 0, northing_m = 0, height_m = 0;
  std::uint16_t red = 0, green = 0, blue = 0;  // 16-bit colour as LAS wants (8-bit value * 257)
  std::uint8_t classification = 1;             // ASPRS: 1 unclassified, 2 ground, 5 high vegetation, 6 building
};

// What a reader finds in a LAS file.
struct LasHeaderInfo {
  std::uint64_t point_count = 0;
  double min_x = 0, min_y = 0, min_z = 0, max_x = 0, max_y = 0, max_z = 0;
  double scale_x = 0, scale_y = 0, scale_z = 0, offset_x = 0, offset_y = 0, offset_z = 0;
  int point_format = 0;
  int version_major = 0, version_minor = 0;
  std::string crs_wkt;  // from the OGC WKT VLR (LASF_Projection, record 2112); empty when there is none
  std::array<std::uint64_t, 16> points_by_class{};  // count per classification 0..15 (uncompressed files only)
  bool compressed = false;  // LAZ: point format with bit 7 set and a "laszip encoded" VLR
  bool copc = false;        // the first VLR is COPC's info VLR
};

enum class PointCloudEncoding {
  kLas,   // uncompressed records
  kLaz,   // LAZ chunks of 50,000 points along a Morton curve
  kCopc,  // LAZ with one chunk per octree node and COPC's info VLR and hierarchy
};
template <>
struct EnumNames<PointCloudEncoding> {
  static constexpr std::array<std::pair<PointCloudEncoding, const char*>, 3> kNames = {
      {{PointCloudEncoding::kLas, "las"}, {PointCloudEncoding::kLaz, "laz"}, {PointCloudEncoding::kCopc, "copc"}}};
};

// The product's file name for each encoding (<stem>.las, <stem>.laz,
// <stem>.copc.laz: COPC's own suffix) and its media type. An AOI's cloud is
// "points", its city's "points_city".
std::string PointCloudFileName(PointCloudEncoding encoding, const std::string& stem = "points");
std::string PointCloudMediaType(PointCloudEncoding encoding);

// Scale of the stored integer coordinates on all axes: millimetres, finer
// than any photogrammetric height.
constexpr double kLasScaleM = 0.001;

// Writes LAS 1.4, point data record format 7 (XYZ int32 scaled, intensity 0,
// return 1 of 1, classification, RGB), global encoding bit 4 (WKT CRS) set and
// one OGC coordinate system WKT VLR holding `crs_wkt`: give the horizontal +
// vertical CRS (WKT2 or WKT1 from GDAL). Offsets are each axis' minimum rounded
// down to a whole metre; the header bounds are those of the stored (quantized)
// coordinates. An empty cloud is a valid file with 0 points and zero bounds.
// The file is built in memory and written atomically. Throws Error naming the
// path when `crs_wkt` is empty or too long for a VLR, or naming the path and
// the point's index when a coordinate is not finite or out of int32 range.
// LAZ and COPC hold the same records, reordered along the space-filling
// curve their compression wants.
void WriteLas(const std::string& path, const std::vector<LasPoint>& points, const std::string& crs_wkt,
              PointCloudEncoding encoding = PointCloudEncoding::kLas);

// Reads the header, the WKT VLR and (uncompressed files) all point records
// back: a parse of its own, sharing nothing with the writer but the structs;
// LAZ records are left to LAZ decoders. Throws Error naming the path when the
// file is not LAS ("LASF"), is truncated, or has a point format this reader
// does not know.
LasHeaderInfo ReadLasHeader(const std::string& path);

}  // namespace skyfall
