// The RPC00B rational polynomial camera (78 coefficients + 10 normalization
// terms), as used by WorldView-3, GDAL, NITF and DigitalGlobe .RPB files.
//
// Conventions:
//  - Geodetic input: longitude and latitude in degrees (WGS84), height in
//    metres above the WGS84 ellipsoid.
//  - Image output: (col, row) = (sample, line) in pixels with pixel centres at
//    integer coordinates, the RPC00B convention used by rpcm, s2p and Sat-NeRF.
//    (GDAL's pixel/line places the top-left pixel corner at 0; see
//    ingest/gdal_rpc_check.h.)
//  - Everything in double: the normalized polynomial is evaluated near its
//    offsets but the offsets themselves are large.
#pragma once

#include <Eigen/Core>
#include <array>
#include <map>
#include <string>

namespace skyfall {

// `lon_deg - ref_deg` taken into [-180, 180): the signed way round the
// circle, for longitudes on both sides of the antimeridian.
double LongitudeDeltaDeg(double lon_deg, double ref_deg);
// `lon_deg` moved by whole turns into [-180, 180).
double WrapLongitudeDeg(double lon_deg);

struct RpcModel {
  // Normalization: x_normalized = (x - offset) / scale.
  double line_off = 0.0;      // row offset [px]
  double samp_off = 0.0;      // column offset [px]
  double lat_off = 0.0;       // [deg]
  double lon_off = 0.0;       // [deg]
  double height_off = 0.0;    // [m]
  double line_scale = 1.0;    // [px]
  double samp_scale = 1.0;    // [px]
  double lat_scale = 1.0;     // [deg]
  double lon_scale = 1.0;     // [deg]
  double height_scale = 1.0;  // [m]
  // Cubic polynomials in (L = lon, P = lat, H = height), normalized, in the
  // RPC00B term order: 1 L P H LP LH PH L2 P2 H2 PLH L3 LP2 LH2 L2P P3 PH2 L2H P2H H3.
  std::array<double, 20> line_num{};
  std::array<double, 20> line_den{};
  std::array<double, 20> samp_num{};
  std::array<double, 20> samp_den{};
  double err_bias_m = -1.0;  // RMS bias error [m]; -1 when unknown
  double err_rand_m = -1.0;  // RMS random error [m]; -1 when unknown

  // Checks that every field is finite, scales are non-zero and both
  // denominators stay away from zero over the whole normalized validity cube
  // [-1, 1]^3. Throws Error("rpc", "", ...) naming the field (GDAL key names).
  void Validate() const;

  // (lon, lat, height) -> (col, row). Throws Error if a denominator is zero at
  // that point. Longitudes are taken modulo 360 around LONG_OFF, so an AOI
  // astride the antimeridian projects alike with 179.9999 or -180.0001.
  Eigen::Vector2d Project(double lon_deg, double lat_deg, double height_m) const;

  // Same, plus the Jacobian d(col, row)/d(lon_deg, lat_deg).
  Eigen::Vector2d Project(double lon_deg, double lat_deg, double height_m,
                          Eigen::Matrix2d* d_colrow_d_lonlat) const;

  // The RPC of the sub-window whose top-left pixel is (col0, row0) of this
  // image: an exact offset shift, so crops stay exact.
  RpcModel Cropped(double col0, double row0) const;
};

struct LocalizeOptions {
  double tolerance_px = 1e-9;  // stop when the image-space residual is below this [px]
  int max_iterations = 50;     // Newton iterations before giving up
  // The iteration is declared divergent when a normalized coordinate leaves
  // [-max_normalized, max_normalized]; the polynomial means nothing there.
  double max_normalized = 10.0;
};

// (col, row, height) -> (lon, lat) in degrees by damped Newton iteration on
// Project. Throws Error("rpc", ...) naming the pixel and height when it does
// not converge, instead of returning a wrong point.
Eigen::Vector2d Localize(const RpcModel& rpc, double col, double row, double height_m,
                         const LocalizeOptions& options = {});

// GDAL "RPC" metadata domain keys (LINE_OFF, ..., SAMP_DEN_COEFF) <-> model.
// The same keys appear in GeoTIFF RPC tags, NITF RPC00B and _RPC.TXT files as
// GDAL reports them. A value may carry one unit word after the number
// ("+005124.00 pixels", as IKONOS writes and GDAL passes on). Parsing throws
// Error naming the missing or bad key, then validates the model.
RpcModel RpcFromGdalMetadata(const std::map<std::string, std::string>& keys);
std::map<std::string, std::string> RpcToGdalMetadata(const RpcModel& rpc);

// DigitalGlobe .RPB text ("lineOffset = ...; lineNumCoef = ( ... );").
RpcModel RpcFromRpbText(const std::string& text);

// "KEY: value" RPC text, one value a line, the polynomials as LINE_NUM_COEFF_1
// .. _20 (the _RPC.TXT / _rpc.txt of IKONOS, GeoEye, SkySat and PlanetScope;
// values may carry unit words). Offsets are taken as written: these files
// follow the RPC00B convention (first pixel centre at 0), as GDAL and rpcm read
// them. Errors name the file's own key (LINE_NUM_COEFF_7).
RpcModel RpcFromKeyValueText(const std::string& text);

}  // namespace skyfall
