#include "testcity/testcity.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <numeric>
#include <random>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "core/height.h"
#include "core/rpc_fit.h"
#include "ingest/geo.h"
#include "ingest/raster.h"
#include "testcity/acquisition.h"

namespace skyfall::synth {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// The options a scene was made with (synth_report.json's "options"), so
// that a drawn scene can be described and made again.
json SceneOptionsJson(const SynthOptions& o) {
  return {{"seed", o.seed},
          {"size_m", o.size_m},
          {"gsd_m", o.gsd_m},
          {"views", o.views},
          {"views_per_date", o.views_per_date},
          {"lat_deg", o.lat_deg},
          {"lon_deg", o.lon_deg},
          {"min_off_nadir_deg", o.min_off_nadir_deg},
          {"max_off_nadir_deg", o.max_off_nadir_deg},
          {"bit_depth", o.bit_depth},
          {"bands", o.bands},
          {"max_building_m", o.max_building_m},
          {"relief_m", o.relief_m},
          {"date_contrast", o.date_contrast},
          {"haze", o.haze},
          {"noise_dn", o.noise_dn},
          {"blur_px", o.blur_px},
          {"clouds", o.clouds},
          {"rpc_height_offset_m", o.rpc_height_offset_m},
          {"ground_height_m", o.ground_height_m},
          {"rpc_bias_px", o.rpc_bias_px},
          {"rpc_bias_rotation_deg", o.rpc_bias_rotation_deg},
          {"views_per_aoi", o.views_per_aoi},
          {"along_track_deg", o.along_track_deg}};
}

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kEarthRadiusM = 6371000.0;  // spherical Earth for the orbit geometry
constexpr double kRpcHeightPadM = 5.0;       // RPC fit domain beyond the scene's height range

// Low-discrepancy sequence value in [0, 1) for view parameters.
double Frac(double x) { return x - std::floor(x); }

Eigen::Vector3d UnitFromAngles(double zenith_rad, double azimuth_rad) {
  return {std::sin(zenith_rad) * std::sin(azimuth_rad), std::sin(zenith_rad) * std::cos(azimuth_rad),
          std::cos(zenith_rad)};
}

// Everything that maps between the scene frame, geodetic and ENU.
struct Georef {
  UtmZone zone;
  double e0 = 0, n0 = 0;  // UTM of the scene-frame origin
  EnuFrame frame{GeodeticPoint{}};

  GeodeticPoint GeodeticFromScene(const Eigen::Vector3d& s) const {
    const Eigen::Vector2d ll = GeodeticFromUtm(zone, e0 + s.x(), n0 + s.y());
    return {ll.x(), ll.y(), s.z()};
  }
  Eigen::Vector3d EnuFromScene(const Eigen::Vector3d& s) const {
    return frame.EnuFromGeodetic(GeodeticFromScene(s));
  }
};

SceneFromEnu FitSceneFromEnu(const Georef& g, const City& city) {
  // Least squares over a grid spanning the city, margin and height range.
  std::vector<Eigen::Vector3d> scene, enu;
  const double x0 = city.origin_m.x(), y0 = city.origin_m.y();
  const double x1 = x0 + city.nx * city.options.cell_m, y1 = y0 + city.ny * city.options.cell_m;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 5; ++i) {
        const Eigen::Vector3d s(x0 + (x1 - x0) * i / 4.0, y0 + (y1 - y0) * j / 4.0,
                                city.min_height_m + (city.max_height_m - city.min_height_m) * k / 2.0);
        scene.push_back(s);
        enu.push_back(g.EnuFromScene(s));
      }
  Eigen::MatrixXd A(scene.size(), 4);
  Eigen::MatrixXd B(scene.size(), 3);
  for (size_t r = 0; r < scene.size(); ++r) {
    A.row(r) << enu[r].x(), enu[r].y(), enu[r].z(), 1.0;
    B.row(r) = scene[r].transpose();
  }
  const Eigen::MatrixXd X = A.colPivHouseholderQr().solve(B);  // 4x3
  SceneFromEnu m;
  m.linear = X.topRows(3).transpose();
  m.offset_m = X.row(3).transpose();
  for (size_t r = 0; r < scene.size(); ++r)
    m.max_error_m = std::max(m.max_error_m, (m.Apply(enu[r]) - scene[r]).norm());
  return m;
}

struct ViewGeometry {
  SatelliteCamera camera;
  double off_nadir_deg, zenith_deg, azimuth_deg, range_m;
};

ViewGeometry MakeCamera(const SynthOptions& o, const Georef& g, const City& city, double ax0,
                        double ay0, int v) {
  ViewGeometry vg;
  const double seed_turn = static_cast<double>(o.seed % 360);
  vg.off_nadir_deg = o.min_off_nadir_deg + (o.max_off_nadir_deg - o.min_off_nadir_deg) * Frac(0.5 + v * 0.618034);
  vg.azimuth_deg = std::fmod(v * 137.508 + 23.0 + seed_turn, 360.0);
  double roll = (-25.0 + 50.0 * Frac(0.3 + v * 0.754877)) * kDegToRad;
  if (o.along_track_deg > 0) {
    // A near-polar descending track (heading 190 deg): the forward view looks
    // ahead along it, the backward one behind; the image rows follow the track.
    constexpr double kTrackHeadingDeg = 190.0;
    const double signed_deg = o.views == 1 ? 0.0 : -o.along_track_deg + 2.0 * o.along_track_deg * v / (o.views - 1);
    vg.off_nadir_deg = std::abs(signed_deg);
    // The satellite's azimuth seen from the ground: ahead of the scene on
    // the track (heading) while it looks forward, behind it afterwards.
    vg.azimuth_deg = std::fmod(kTrackHeadingDeg + (signed_deg < 0 ? 180.0 : 0.0), 360.0);
    roll = 0.0;
  }
  const double alpha = vg.off_nadir_deg * kDegToRad;
  const double ratio = (kEarthRadiusM + o.orbit_height_m) / kEarthRadiusM;
  const double zenith = std::asin(std::min(1.0, ratio * std::sin(alpha)));
  vg.zenith_deg = zenith / kDegToRad;
  // Triangle Earth centre - ground - satellite (law of sines).
  vg.range_m = alpha > 1e-9 ? kEarthRadiusM * std::sin(zenith - alpha) / std::sin(alpha) : o.orbit_height_m;
  const double base = city.options.base_height_m;
  const Eigen::Vector3d target = g.EnuFromScene({ax0 + 0.5 * o.size_m, ay0 + 0.5 * o.size_m, base});
  SatelliteCamera& cam = vg.camera;
  cam.centre_enu_m = target + vg.range_m * UnitFromAngles(zenith, vg.azimuth_deg * kDegToRad);
  cam.focal_px = vg.range_m / o.gsd_m;
  const Eigen::Vector3d forward = (target - cam.centre_enu_m).normalized();
  const Eigen::Vector3d right0 = forward.cross(Eigen::Vector3d::UnitY()).normalized();
  const Eigen::Vector3d down0 = forward.cross(right0);
  const Eigen::Vector3d right = std::cos(roll) * right0 + std::sin(roll) * down0;
  const Eigen::Vector3d down = -std::sin(roll) * right0 + std::cos(roll) * down0;
  cam.cam_from_enu.row(0) = right.transpose();
  cam.cam_from_enu.row(1) = down.transpose();
  cam.cam_from_enu.row(2) = forward.transpose();
  // Crop window: the AOI's box over the scene's height range, plus a margin.
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (double z : {static_cast<double>(city.min_height_m), static_cast<double>(city.max_height_m)})
    for (double dx : {0.0, o.size_m})
      for (double dy : {0.0, o.size_m}) {
        const Eigen::Vector2d p = cam.Project(g.EnuFromScene({ax0 + dx, ay0 + dy, z}));
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
  cam.principal_px = -lo + Eigen::Vector2d::Constant(o.image_margin_px);
  cam.width_px = static_cast<int>(std::ceil(hi.x() - lo.x())) + 2 * o.image_margin_px;
  cam.height_px = static_cast<int>(std::ceil(hi.y() - lo.y())) + 2 * o.image_margin_px;
  return vg;
}

// A pointing bias of a written RPC (see SynthOptions::rpc_bias_px).
struct PointingBias {
  Eigen::Vector2d shift_px = Eigen::Vector2d::Zero();
  double rotation_deg = 0.0;
  Eigen::Vector2d Apply(const Eigen::Vector2d& px, const SatelliteCamera& cam) const {
    const Eigen::Vector2d centre(0.5 * (cam.width_px - 1), 0.5 * (cam.height_px - 1));
    return centre + Eigen::Rotation2Dd(rotation_deg * M_PI / 180.0) * (px - centre) + shift_px;
  }
};

// The biases of the city's acquisitions: shifts uniform in a disc of radius
// rpc_bias_px, rotations uniform in +-max. A shift of the whole scene moves
// image i by P_i v (P_i: its projection's Jacobian at the city centre, 2x3),
// which tie points cannot tell from a bias: the part of the shifts such a v
// explains, v = argmin sum |b_i - P_i v|^2, is removed, so that the truth's
// frame is the one bundle adjustment's prior (the images' average) finds.
std::vector<PointingBias> DrawPointingBiases(const SynthOptions& o,
                                             const std::vector<Eigen::Matrix<double, 2, 3>>& jacobians) {
  std::vector<PointingBias> out(o.views);
  if (o.rpc_bias_px <= 0 && o.rpc_bias_rotation_deg <= 0) return out;
  std::mt19937_64 rng(o.seed * 0x9E3779B97F4A7C15ULL + 7777);
  auto unit = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < out.size(); ++i) {
    PointingBias& b = out[i];
    const double r = o.rpc_bias_px * std::sqrt(unit()), t = 2 * M_PI * unit();
    b.shift_px = {r * std::cos(t), r * std::sin(t)};
    b.rotation_deg = o.rpc_bias_rotation_deg * (2 * unit() - 1);
    normal += jacobians[i].transpose() * jacobians[i];
    rhs += jacobians[i].transpose() * b.shift_px;
  }
  const Eigen::Vector3d common_m = normal.completeOrthogonalDecomposition().solve(rhs);
  for (std::size_t i = 0; i < out.size(); ++i) out[i].shift_px -= jacobians[i] * common_m;
  return out;
}

// d(pixel)/d(ENU point) of a camera at `at_enu_m`, by central differences
// over 1 m (the projection is nearly affine over a crop).
Eigen::Matrix<double, 2, 3> ProjectionJacobian(const SatelliteCamera& cam, const Eigen::Vector3d& at_enu_m) {
  Eigen::Matrix<double, 2, 3> j;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d h = Eigen::Vector3d::Unit(k);
    j.col(k) = 0.5 * (cam.Project(at_enu_m + h) - cam.Project(at_enu_m - h));
  }
  return j;
}

RpcFitResult FitViewRpc(const SatelliteCamera& cam, const Georef& g, const City& city, double height_offset_m,
                        const PointingBias& bias) {
  const double z0 = std::min(city.min_height_m - kRpcHeightPadM, city.min_height_m + 2 * height_offset_m);
  const double z1 = std::max(city.max_height_m + kRpcHeightPadM, city.max_height_m + 2 * height_offset_m);
  RpcFitDomain d{1e9, -1e9, 1e9, -1e9, z0, z1};
  // Longitudes are unwrapped around the frame's origin, so that a domain
  // astride the antimeridian is 179.9992..180.0002, not -180..180.
  const double lon_ref = g.frame.GeodeticFromEnu(Eigen::Vector3d::Zero()).lon_deg;
  // The ground under the image corners at both ends of the height range
  // (z0, z1 are ellipsoidal; the rays live in ENU).
  for (double col : {-0.5, cam.width_px - 0.5})
    for (double row : {-0.5, cam.height_px - 0.5}) {
      const Eigen::Vector3d dir = cam.RayDirectionEnu(col, row);
      for (double z : {z0, z1}) {
        const double up_m = EnuUpAtOrigin(EllipsoidHeightM(z), g.frame.origin()).value;
        const Eigen::Vector3d p = cam.centre_enu_m + ((up_m - cam.centre_enu_m.z()) / dir.z()) * dir;
        const GeodeticPoint q = g.frame.GeodeticFromEnu(p);
        const double lon = lon_ref + LongitudeDeltaDeg(q.lon_deg, lon_ref);
        d.min_lon_deg = std::min(d.min_lon_deg, lon);
        d.max_lon_deg = std::max(d.max_lon_deg, lon);
        d.min_lat_deg = std::min(d.min_lat_deg, q.lat_deg);
        d.max_lat_deg = std::max(d.max_lat_deg, q.lat_deg);
      }
    }
  return FitRpc(
      [&](double lon, double lat, double h) {
        return bias.Apply(cam.Project(g.frame.EnuFromGeodetic({lon, lat, h})), cam);
      },
      d);
}

json SatNerfJson(const SynthView& v, const RpcModel& rpc, const std::vector<Eigen::Vector2d>& footprint,
                 const Acquisition& acq, const City& city) {
  auto list = [](const std::array<double, 20>& c) { return std::vector<double>(c.begin(), c.end()); };
  json ring = json::array();
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const auto& p : footprint) {
    ring.push_back({p.x(), p.y()});
    centre += p / static_cast<double>(footprint.size());
  }
  return {{"img", v.name + ".tif"},
          {"width", v.camera.width_px},
          {"height", v.camera.height_px},
          {"sun_elevation", v.sun_elevation_deg},
          {"sun_azimuth", v.sun_azimuth_deg},
          {"acquisition_date", acq.compact},
          {"geojson", {{"type", "Polygon"}, {"coordinates", {ring}}, {"center", {centre.x(), centre.y()}}}},
          {"min_alt", std::floor(city.min_height_m)},
          {"max_alt", std::ceil(city.max_height_m)},
          {"rpc",
           {{"row_offset", rpc.line_off}, {"col_offset", rpc.samp_off}, {"lat_offset", rpc.lat_off},
            {"lon_offset", rpc.lon_off}, {"alt_offset", rpc.height_off}, {"row_scale", rpc.line_scale},
            {"col_scale", rpc.samp_scale}, {"lat_scale", rpc.lat_scale}, {"lon_scale", rpc.lon_scale},
            {"alt_scale", rpc.height_scale}, {"row_num", list(rpc.line_num)},
            {"row_den", list(rpc.line_den)}, {"col_num", list(rpc.samp_num)},
            {"col_den", list(rpc.samp_den)}}}};
}

// Truth rasters of one AOI in the DFC2019 layout: row 0 is the north edge,
// _DSM.txt gives the lower-left corner.
void WriteTruth(const SynthResult& r, const SynthAoi& aoi, const SynthOptions& o, const fs::path& root) {
  const int n = static_cast<int>(std::lround(o.size_m / o.gsd_m));
  std::vector<float> dsm(static_cast<size_t>(n) * n);
  std::vector<std::uint8_t> cls(dsm.size());
  for (int row = 0; row < n; ++row)
    for (int col = 0; col < n; ++col) {
      const double x = aoi.x0_m + (col + 0.5) * o.gsd_m;
      const double y = aoi.y0_m + o.size_m - (row + 0.5) * o.gsd_m;
      const Eigen::Vector2i c = r.city.CellOf(x, y);
      const size_t k = r.city.Index(c.x(), c.y());
      dsm[static_cast<size_t>(row) * n + col] = r.city.height_m[k];
      cls[static_cast<size_t>(row) * n + col] = static_cast<std::uint8_t>(r.city.cls[k]);
    }
  const fs::path truth = root / "Track3-Truth";
  WriteFloatTiff((truth / (aoi.name + "_DSM.tif")).string(), n, n, dsm.data());
  WriteByteTiff((truth / (aoi.name + "_CLS.tif")).string(), n, n, 1, cls.data());
  char txt[256];
  std::snprintf(txt, sizeof(txt), "%f\n%f\n%f\n%f\n", r.utm_easting0_m + aoi.x0_m,
                r.utm_northing0_m + aoi.y0_m, static_cast<double>(n), o.gsd_m);
  WriteFileAtomic((truth / (aoi.name + "_DSM.txt")).string(), txt);
}

}  // namespace

namespace {

// Writes a rendered view with the sensor's bands and bit depth: Byte RGB as
// rendered, else luminance for one band and, above 8 bits, digital numbers
// from a dark offset to 90% of the range (so that a reader dividing by 255
// saturates and one that measures the range does not).
void WriteSensorImage(const std::string& path, const RenderedView& img, const SynthOptions& o,
                      const RasterWriteOptions& write) {
  const std::size_t n = static_cast<std::size_t>(img.width_px) * img.height_px;
  if (o.bit_depth == 8 && o.bands == 3) return WriteByteTiff(path, img.width_px, img.height_px, 3, img.rgb.data(), write);
  std::vector<float> values(n * o.bands);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint8_t* p = &img.rgb[3 * k];
    if (o.bands == 1) {
      values[k] = 0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2];
    } else {
      for (int c = 0; c < 3; ++c) values[3 * k + c] = p[c];
    }
  }
  if (o.bit_depth == 8) {
    std::vector<std::uint8_t> bytes(values.size());
    for (std::size_t k = 0; k < values.size(); ++k) bytes[k] = static_cast<std::uint8_t>(std::lround(values[k]));
    return WriteByteTiff(path, img.width_px, img.height_px, o.bands, bytes.data(), write);
  }
  const double max_dn = std::ldexp(1.0, o.bit_depth) - 1.0, offset = std::ldexp(1.0, o.bit_depth - 6);
  const double gain = (0.9 * max_dn - offset) / 255.0;
  std::vector<std::uint16_t> dn(values.size());
  for (std::size_t k = 0; k < values.size(); ++k) dn[k] = static_cast<std::uint16_t>(std::lround(offset + gain * values[k]));
  WriteUInt16Tiff(path, img.width_px, img.height_px, o.bands, dn.data(), write);
}

// <AOI>_ORTHO.tif beside the truth DSM, on its grid: the city's exact true
// orthophoto (RenderOrtho), lit as the AOI's view closest to nadir and
// written with the sensor's bands and bit depth, so that it reads with that
// view's radiometry.
void WriteOrthoTruth(const SynthResult& r, const SynthAoi& aoi, const SynthOptions& o, const fs::path& root) {
  if (aoi.views.empty()) return;
  const SynthView& nadir = *std::min_element(aoi.views.begin(), aoi.views.end(), [](const SynthView& a, const SynthView& b) {
    return a.view_zenith_deg < b.view_zenith_deg;
  });
  const int n = static_cast<int>(std::lround(o.size_m / o.gsd_m));
  RenderedView ortho;
  ortho.width_px = ortho.height_px = n;
  ortho.rgb = RenderOrtho(r.city, nadir.lighting, aoi.x0_m, aoi.y0_m + o.size_m, o.gsd_m, n, n);
  RasterWriteOptions write;
  write.metadata["LIT_AS"] = nadir.name;
  WriteSensorImage((root / "Track3-Truth" / (aoi.name + "_ORTHO.tif")).string(), ortho, o, write);
}

// Uniform in [0, 1) from the generator's top 53 bits.
double Unit(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }
double Uniform(std::mt19937_64& rng, double lo, double hi) { return lo + (hi - lo) * Unit(rng); }
template <typename T, std::size_t N>
T Pick(std::mt19937_64& rng, const std::array<T, N>& values) {
  return values[std::min(N - 1, static_cast<std::size_t>(Unit(rng) * N))];
}
// Drawn angles and lengths are kept to a tenth: the options read back the same from the report.
double Tenth(double v) { return std::round(v * 10.0) / 10.0; }

}  // namespace

SynthOptions DrawSceneOptions(std::uint64_t draw, const SynthOptions& base) {
  // The generator is seeded by the draw number; the city's own seed is drawn
  // from it, offset so that it never meets the small seeds used for tuning.
  std::mt19937_64 rng(0x5eedULL ^ (draw * 0x9E3779B97F4A7C15ULL));
  SynthOptions o = base;
  o.seed = 1000000 + (rng() % 1000000000ULL);
  o.lat_deg = Tenth(Uniform(rng, -60.0, 60.0));
  o.lon_deg = Tenth(Uniform(rng, -180.0, 180.0));
  o.min_off_nadir_deg = Tenth(Uniform(rng, 0.0, 20.0));
  o.max_off_nadir_deg = std::min(45.0, Tenth(o.min_off_nadir_deg + Uniform(rng, 10.0, 25.0)));
  o.views = Pick(rng, std::array<int, 7>{3, 4, 6, 8, 10, 12, 16});
  o.views_per_date = std::min(o.views, Pick(rng, std::array<int, 3>{1, 2, 3}));
  o.bands = Unit(rng) < 1.0 / 3.0 ? 1 : 3;
  o.bit_depth = Pick(rng, std::array<int, 5>{8, 11, 12, 14, 16});
  o.relief_m = Unit(rng) < 0.5 ? 0.0 : Tenth(Uniform(rng, 10.0, 100.0));
  o.max_building_m = Tenth(Uniform(rng, 15.0, 180.0));
  o.date_contrast = Tenth(Uniform(rng, 0.5, 3.0));
  o.Check();
  return o;
}

void SynthOptions::Check() const {
  auto need = [](bool ok, const char* field, const std::string& value, const char* rule) {
    if (!ok) throw Error("synth", field, value + " is invalid: " + rule);
  };
  need(!aoi.empty() && aoi.find('/') == std::string::npos && aoi.find('_') != std::string::npos &&
           std::isdigit(static_cast<unsigned char>(aoi.back())),
       "aoi", "'" + aoi + "'", "must look like NAME_NNN (e.g. SYN_001) so images parse as DFC2019");
  need(size_m >= 32 && size_m <= 4096, "size_m", FormatDouble(size_m), "must be 32..4096 m");
  need(gsd_m >= 0.1 && gsd_m <= 5, "gsd_m", FormatDouble(gsd_m), "must be 0.1..5 m");
  need(std::abs(size_m / gsd_m - std::round(size_m / gsd_m)) < 1e-9, "size_m",
       FormatDouble(size_m), "must be a whole number of gsd_m");
  need(views >= 2 && views <= 200, "views", std::to_string(views), "must be 2..200");
  need(views_per_date >= 1, "views_per_date", std::to_string(views_per_date), "must be >= 1");
  need(std::abs(lat_deg) <= 80, "lat_deg", FormatDouble(lat_deg), "must be within UTM (-80..80)");
  need(std::abs(lon_deg) <= 180, "lon_deg", FormatDouble(lon_deg), "must be -180..180");
  need(blocks_x >= 1 && blocks_x <= 16, "blocks_x", std::to_string(blocks_x), "must be 1..16");
  need(blocks_y >= 1 && blocks_y <= 16, "blocks_y", std::to_string(blocks_y), "must be 1..16");
  need(min_off_nadir_deg >= 0 && min_off_nadir_deg <= max_off_nadir_deg && max_off_nadir_deg <= 45,
       "max_off_nadir_deg", FormatDouble(max_off_nadir_deg), "need 0 <= min <= max <= 45 deg");
  need(bit_depth == 8 || (bit_depth >= 11 && bit_depth <= 16), "bit_depth", std::to_string(bit_depth),
       "must be 8 or 11..16");
  need(max_building_m >= 6 && max_building_m <= 600, "max_building_m", FormatDouble(max_building_m), "must be 6..600 m");
  need(relief_m >= 0 && relief_m <= 1000, "relief_m", FormatDouble(relief_m), "must be 0..1000 m");
  need(date_contrast >= 0 && date_contrast <= 4, "date_contrast", FormatDouble(date_contrast), "must be 0..4");
  need(haze >= 0 && haze <= 0.9, "haze", FormatDouble(haze), "must be 0..0.9");
  need(noise_dn >= 0 && noise_dn <= 20, "noise_dn", FormatDouble(noise_dn), "must be 0..20 DN");
  need(blur_px >= 0 && blur_px <= 3, "blur_px", FormatDouble(blur_px), "must be 0..3 px");
  need(clouds >= 0 && clouds <= 0.8, "clouds", FormatDouble(clouds), "must be 0..0.8");
  need(bands == 1 || bands == 3, "bands", std::to_string(bands), "must be 1 (panchromatic) or 3 (RGB)");
  need(orbit_height_m >= 200e3 && orbit_height_m <= 2000e3, "orbit_height_m",
       FormatDouble(orbit_height_m), "must be 200..2000 km");
  need(std::abs(rpc_height_offset_m) <= 5000, "rpc_height_offset_m", FormatDouble(rpc_height_offset_m),
       "must be -5000..5000 m");
  need(ground_height_m >= -500 && ground_height_m <= 8000, "ground_height_m", FormatDouble(ground_height_m),
       "must be -500..8000 m above the ellipsoid");
  need(rpc_bias_px >= 0 && rpc_bias_px <= 50, "rpc_bias_px", FormatDouble(rpc_bias_px), "must be 0..50 px");
  // Bundle adjustment models a bias as a shift; 0.1 deg turns a 600 px crop's
  // corners by 0.5 px, which it cannot absorb.
  need(rpc_bias_rotation_deg >= 0 && rpc_bias_rotation_deg <= 0.1, "rpc_bias_rotation_deg",
       FormatDouble(rpc_bias_rotation_deg), "must be 0..0.1 deg");
  need(views_per_aoi == 0 || (views_per_aoi >= 2 && views_per_aoi <= views), "views_per_aoi",
       std::to_string(views_per_aoi), "must be 0 (all) or 2..views");
  need(along_track_deg >= 0 && along_track_deg <= 45, "along_track_deg", FormatDouble(along_track_deg),
       "must be 0..45 deg");
  need(along_track_deg == 0 || views_per_date == views, "views_per_date", std::to_string(views_per_date),
       "must equal views with along_track_deg (a three-line camera takes its views on one pass)");
  need(cars_per_block >= 0, "cars_per_block", std::to_string(cars_per_block), "must be >= 0");
  need(image_margin_px >= 0, "image_margin_px", std::to_string(image_margin_px), "must be >= 0");
}

namespace {

// The city and its georeferencing, as RunSynth and RenderTruthViews share them.
struct Scene {
  CityOptions city_options;
  Georef georef;
};

Scene MakeScene(const SynthOptions& o, SynthResult* r) {
  Scene sc;
  CityOptions& co = sc.city_options;
  co.width_m = o.blocks_x * o.size_m;
  co.height_m = o.blocks_y * o.size_m;
  co.cell_m = 0.5 * o.gsd_m;  // two cells per DSM pixel: DSM pixel centres are cell centres
  // Terrain beyond the AOIs: the corners of rotated, oblique crops look up to
  // about half an AOI side further out, plus the lean of the tallest buildings.
  const double lean_m = o.max_building_m * std::tan(o.max_off_nadir_deg * M_PI / 180.0);
  const double margin_m = 0.45 * o.size_m + std::max(64.0, lean_m);
  co.margin_m = std::ceil(margin_m / o.gsd_m) * o.gsd_m;
  co.seed = o.seed;
  co.base_height_m = o.ground_height_m;
  co.max_building_m = o.max_building_m;
  co.relief_m = o.relief_m;
  co.water = o.relief_m <= 10.0;
  r->city = GenerateCity(co);

  Georef& g = sc.georef;
  g.zone = StandardUtmZone(o.lon_deg, o.lat_deg);
  const Eigen::Vector2d centre_en = UtmFromGeodetic(g.zone, o.lon_deg, o.lat_deg);
  g.e0 = std::round(centre_en.x() - 0.5 * co.width_m);
  g.n0 = std::round(centre_en.y() - 0.5 * co.height_m);
  const GeodeticPoint centre = g.GeodeticFromScene({0.5 * co.width_m, 0.5 * co.height_m, co.base_height_m});
  g.frame = EnuFrame(centre);
  r->enu_origin = centre;
  r->utm_easting0_m = g.e0;
  r->utm_northing0_m = g.n0;
  r->epsg = g.zone.Epsg();
  r->scene_from_enu = FitSceneFromEnu(g, r->city);
  return sc;
}

// The cumulus of a cloudy date: puffs 60-200 m in radius, uniform over the
// city and far enough beyond it that every view's and every shadow's ray
// over the city can meet one (a cloud 1 km up is seen up to 1 km aside at
// 45 deg off nadir, its shadow up to 3 km aside under a low sun), as many
// as cover `o.clouds` of that area before overlaps.
CloudLayer CloudsOfDate(const SynthOptions& o, const City& city, int date) {
  constexpr double kAboveTallestM = 1000.0, kMarginM = 3500.0, kMinRadiusM = 60.0, kMaxRadiusM = 200.0;
  CloudLayer layer;
  layer.height_m = city.max_height_m + kAboveTallestM;
  const double x0 = -kMarginM, y0 = -kMarginM;
  const double x1 = o.blocks_x * o.size_m + kMarginM, y1 = o.blocks_y * o.size_m + kMarginM;
  // Mean puff area: pi E[r^2] for r uniform in [a, b].
  const double a = kMinRadiusM, b = kMaxRadiusM;
  const double mean_area_m2 = M_PI * (a * a + a * b + b * b) / 3.0;
  const auto count = static_cast<std::size_t>(std::lround(o.clouds * (x1 - x0) * (y1 - y0) / mean_area_m2));
  std::mt19937_64 rng(o.seed * 0x9E3779B97F4A7C15ULL + 0xC10D + static_cast<std::uint64_t>(date));
  for (std::size_t i = 0; i < count; ++i) {
    CloudPuff puff;
    puff.centre_m = {Uniform(rng, x0, x1), Uniform(rng, y0, y1)};
    puff.radius_m = Uniform(rng, a, b);
    layer.puffs.push_back(puff);
  }
  return layer;
}

// When image v (0-based) was taken: its date, its shot within that date's
// pass, and the scene's longitude decide it.
Acquisition ViewAcquisition(const SynthOptions& o, int v) {
  return MakeAcquisition(v / o.views_per_date, v % o.views_per_date, o.lon_deg);
}

// The light of image v (0-based) of the AOI at block (bx, by); fills the
// view's time and sun angles.
Lighting ViewLighting(const SynthOptions& o, const SynthResult& r, int v, int bx, int by, SynthView* view) {
  const int date = v / o.views_per_date;
  const Acquisition acq = ViewAcquisition(o, v);
  view->acquisition_time = acq.iso;
  SunPosition(o.lat_deg, o.lon_deg, acq, &view->sun_elevation_deg, &view->sun_azimuth_deg);
  Lighting light;
  light.sun_scene = (r.scene_from_enu.linear *
                     UnitFromAngles((90.0 - view->sun_elevation_deg) * kDegToRad, view->sun_azimuth_deg * kDegToRad))
                        .normalized();
  const double s = o.date_contrast;
  light.gain = static_cast<float>(1.0 + s * 0.24 * (Frac(0.17 + date * 0.4142 + o.seed * 0.1) - 0.5));
  light.ambient = static_cast<float>(0.28 + 0.12 * Frac(0.61 + date * 0.7071));
  light.tint = Eigen::Vector3f(1.0f + static_cast<float>(s * 0.05 * (Frac(date * 0.31) - 0.5)), 1.0f,
                               1.0f + static_cast<float>(s * 0.08 * (Frac(date * 0.53) - 0.5)));
  light.noise_seed = o.seed * 100003 + static_cast<std::uint64_t>(by * 1000 + bx * 100 + v);
  light.haze = static_cast<float>(o.haze);
  light.noise_dn = static_cast<float>(o.noise_dn);
  light.blur_px = static_cast<float>(o.blur_px);
  if (o.clouds > 0 && date % 2 == 1) light.clouds = CloudsOfDate(o, r.city, date);
  return light;
}

}  // namespace

namespace {

// One view of an AOI: its camera, lighting, fitted (and biased) RPC, image
// and Sat-NeRF JSON.
SynthView SynthesizeView(const SynthOptions& o, const Scene& scene, const SynthResult& r, const SynthAoi& aoi,
                         const fs::path& root, int bx, int by, int v, const ViewGeometry& vg, const PointingBias& bias,
                         const City& city_of_date) {
  const CityOptions& co = scene.city_options;
  const Georef& g = scene.georef;
  const Acquisition acq = ViewAcquisition(o, v);
  SynthView view;
  char name[64];
  std::snprintf(name, sizeof(name), "%s_%03d_RGB", aoi.name.c_str(), v + 1);
  view.name = name;
  view.path = (root / "Track3-RGB-crops" / aoi.name / (view.name + ".tif")).string();
  view.camera = vg.camera;
  view.off_nadir_deg = vg.off_nadir_deg;
  view.view_zenith_deg = vg.zenith_deg;
  view.view_azimuth_deg = vg.azimuth_deg;
  view.range_km = vg.range_m / 1000.0;
  view.lighting = ViewLighting(o, r, v, bx, by, &view);

  const RpcFitResult fit = FitViewRpc(view.camera, g, r.city, o.rpc_height_offset_m, bias);
  view.rpc_bias_shift_px = bias.shift_px;
  view.rpc_bias_rotation_deg = bias.rotation_deg;
  view.rpc_fit_max_px = fit.max_residual_px;
  view.rpc_fit_rms_px = fit.rms_residual_px;

  const RenderedView img = RenderView(city_of_date, view.camera, r.scene_from_enu, view.lighting);
  view.cloud_covered_fraction = img.cloud_covered_fraction;
  RasterWriteOptions wo;
  wo.metadata["NITF_IDATIM"] = acq.compact;
  wo.rpc_metadata = RpcToGdalMetadata(fit.rpc);
  WriteSensorImage(view.path, img, o, wo);

  std::vector<Eigen::Vector2d> footprint;
  for (const auto& c : {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(img.width_px - 0.5, -0.5),
                        Eigen::Vector2d(img.width_px - 0.5, img.height_px - 0.5),
                        Eigen::Vector2d(-0.5, img.height_px - 0.5)}) {
    footprint.push_back(Localize(fit.rpc, c.x(), c.y(), co.base_height_m));
  }
  WriteFileAtomic((root / "satnerf-rpcs" / aoi.name / (view.name + ".json")).string(),
                  SatNerfJson(view, fit.rpc, footprint, acq, r.city).dump(2) + "\n");
  return view;
}

// Sat-NeRF-style split: of the AOI's images, the second one and the one
// after the middle are held out.
void WriteSplit(const SynthAoi& aoi, const fs::path& root) {
  const fs::path json_dir = root / "satnerf-rpcs" / aoi.name;
  const int n = static_cast<int>(aoi.views.size());
  std::string train, test;
  for (int k = 0; k < n; ++k) {
    const bool held_out = n >= 4 && (k == 1 || k == (n / 2) + 1);
    (held_out ? test : train) += aoi.views[k].name + "\n";
  }
  WriteFileAtomic((json_dir / "train.txt").string(), train);
  WriteFileAtomic((json_dir / "test.txt").string(), test);
}

// The biases of the city's acquisitions (DrawPointingBiases), with each
// acquisition's Jacobian at the city centre: a crop only offsets its pixels.
std::vector<PointingBias> CityPointingBiases(const SynthOptions& o, const Scene& scene, const City& city) {
  const Eigen::Vector3d centre_enu = scene.georef.EnuFromScene(
      {0.5 * o.blocks_x * o.size_m, 0.5 * o.blocks_y * o.size_m, scene.city_options.base_height_m});
  std::vector<Eigen::Matrix<double, 2, 3>> jacobians;
  for (int v = 0; v < o.views; ++v)
    jacobians.push_back(ProjectionJacobian(MakeCamera(o, scene.georef, city, 0.0, 0.0, v).camera, centre_enu));
  return DrawPointingBiases(o, jacobians);
}

// The acquisitions AOI number `aoi_index` holds, in order: all, or a seeded
// choice of views_per_aoi of them.
std::vector<int> AoiAcquisitions(const SynthOptions& o, int aoi_index) {
  std::vector<int> all(o.views);
  std::iota(all.begin(), all.end(), 0);
  if (o.views_per_aoi <= 0 || o.views_per_aoi >= o.views) return all;
  std::mt19937_64 rng(o.seed * 0x9E3779B97F4A7C15ULL + 4242 + aoi_index);
  std::shuffle(all.begin(), all.end(), rng);
  all.resize(o.views_per_aoi);
  std::sort(all.begin(), all.end());
  return all;
}

// Block (bx, by) of the city: its views, split and truth.
SynthAoi SynthesizeAoi(const SynthOptions& o, const Scene& scene, int bx, int by, const std::vector<PointingBias>& biases,
                       const fs::path& root, const SynthResult& r, Progress& progress, std::size_t* done) {
  SynthAoi aoi;
  aoi.name = (o.blocks_x * o.blocks_y == 1) ? o.aoi : o.aoi + "_X" + std::to_string(bx) + "Y" + std::to_string(by);
  aoi.x0_m = bx * o.size_m;
  aoi.y0_m = by * o.size_m;
  std::map<int, City> with_cars;  // per date: transient objects move between passes
  for (const int v : AoiAcquisitions(o, static_cast<int>(r.aois.size()))) {
    const int date = v / o.views_per_date;
    if (!with_cars.count(date)) {
      with_cars.emplace(date, WithCars(r.city, o.cars_per_block * o.blocks_x * o.blocks_y, o.seed * 7919 + date));
    }
    const City& city_of_date = with_cars.at(date);
    const ViewGeometry geometry = MakeCamera(o, scene.georef, r.city, aoi.x0_m, aoi.y0_m, v);
    aoi.views.push_back(SynthesizeView(o, scene, r, aoi, root, bx, by, v, geometry, biases[v], city_of_date));
    progress.Advance(++*done, aoi.views.back().name);
  }
  WriteSplit(aoi, root);
  WriteTruth(r, aoi, o, root);
  WriteOrthoTruth(r, aoi, o, root);
  return aoi;
}

json SynthReportJson(const SynthOptions& o, const SynthResult& r, double worst_fit_px) {
  json report = {{"seed", o.seed},
                 {"options", SceneOptionsJson(o)},
                 {"epsg", r.epsg},
                 {"utm_origin_m", {r.utm_easting0_m, r.utm_northing0_m}},
                 {"buildings", r.city.buildings.size()},
                 {"height_range_m", {r.city.min_height_m, r.city.max_height_m}},
                 {"scene_from_enu_max_error_m", r.scene_from_enu.max_error_m},
                 {"rpc_fit_max_residual_px", worst_fit_px},
                 {"dates", (o.views + o.views_per_date - 1) / o.views_per_date}};
  json images = json::array();
  for (const auto& aoi : r.aois)
    for (const auto& v : aoi.views)
      images.push_back({{"aoi", aoi.name}, {"name", v.name}, {"acquisition_time", v.acquisition_time},
                        {"off_nadir_deg", v.off_nadir_deg}, {"view_zenith_deg", v.view_zenith_deg},
                        {"view_azimuth_deg", v.view_azimuth_deg}, {"range_km", v.range_km},
                        {"sun_elevation_deg", v.sun_elevation_deg}, {"sun_azimuth_deg", v.sun_azimuth_deg},
                        {"rpc_fit_max_px", v.rpc_fit_max_px}, {"rpc_fit_rms_px", v.rpc_fit_rms_px},
                        {"rpc_bias_shift_px", {v.rpc_bias_shift_px.x(), v.rpc_bias_shift_px.y()}},
                        {"rpc_bias_rotation_deg", v.rpc_bias_rotation_deg},
                        {"cloud_covered_fraction", v.cloud_covered_fraction},
                        {"width_px", v.camera.width_px}, {"height_px", v.camera.height_px}});
  report["images"] = images;
  return report;
}

}  // namespace

SynthResult RunSynth(const SynthOptions& o, const std::string& root_dir, Progress& progress) {
  o.Check();
  Stopwatch clock;
  SynthResult r;
  r.report.stage = "synth";
  const Scene scene = MakeScene(o, &r);
  const fs::path root(root_dir);
  const int views_per_aoi = o.views_per_aoi > 0 ? std::min(o.views_per_aoi, o.views) : o.views;
  progress.Begin("synth render", static_cast<size_t>(views_per_aoi) * o.blocks_x * o.blocks_y);
  const std::vector<PointingBias> biases = CityPointingBiases(o, scene, r.city);
  std::size_t done = 0;
  for (int by = 0; by < o.blocks_y; ++by) {
    for (int bx = 0; bx < o.blocks_x; ++bx) {
      r.aois.push_back(SynthesizeAoi(o, scene, bx, by, biases, root, r, progress, &done));
    }
  }
  progress.End();
  double worst_fit = 0;
  for (const SynthAoi& aoi : r.aois)
    for (const SynthView& v : aoi.views) worst_fit = std::max(worst_fit, v.rpc_fit_max_px);

  json report = SynthReportJson(o, r, worst_fit);
  r.report.seconds = clock.Seconds();
  report["seconds"] = r.report.seconds;
  WriteFileAtomic((root / "synth_report.json").string(), report.dump(2) + "\n");
  r.report.metrics["rpc_fit_max_residual_px"] = worst_fit;
  r.report.metrics["images"] = static_cast<double>(done);
  r.report.metrics["buildings"] = static_cast<double>(r.city.buildings.size());
  return r;
}

int RenderTruthViews(const SynthOptions& o, const std::vector<std::pair<std::string, PinholeCamera>>& cameras,
                     const GeodeticPoint& cameras_origin, int lighting_view, const std::string& out_dir,
                     Progress& progress) {
  o.Check();
  if (lighting_view < 0 || lighting_view >= o.views)
    throw Error("synth", "lighting view", std::to_string(lighting_view) + " is not an image of 0.." + std::to_string(o.views - 1));
  SynthResult r;
  const Scene scene = MakeScene(o, &r);
  const EnuFrame given(cameras_origin);
  const EnuFrame& own = scene.georef.frame;
  SynthView lit;
  // Low orbit cameras fly below any cloud layer: the truth images are of a clear sky.
  Lighting light = ViewLighting(o, r, lighting_view, 0, 0, &lit);
  light.clouds = CloudLayer();
  // Directions in the cameras' frame from directions in the city's ENU frame
  // (the two frames differ by the Earth's curvature between their origins).
  auto own_from_given = [&](const Eigen::Vector3d& p) { return own.EnuFromGeodetic(given.GeodeticFromEnu(p)); };
  fs::create_directories(out_dir);
  progress.Begin("synth truth views", cameras.size());
  int written = 0;
  for (const auto& [name, cam] : cameras) {
    if (std::abs(cam.fx - cam.fy) > 1e-6 * cam.fx || std::abs(cam.skew) > 1e-6 * cam.fx)
      throw Error("synth", name, "truth views need square pixels without skew");
    const Eigen::Vector3d centre_given = cam.Centre();
    const Eigen::Vector3d centre_own = own_from_given(centre_given);
    Eigen::Matrix3d given_from_own;  // columns: the city frame's axes in the cameras' frame
    constexpr double kStepM = 10.0;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d step_own = centre_own + kStepM * Eigen::Vector3d::Unit(k);
      given_from_own.col(k) = (given.EnuFromGeodetic(own.GeodeticFromEnu(step_own)) - centre_given) / kStepM;
    }
    SatelliteCamera sc;
    sc.cam_from_enu = cam.cam_from_world_rotation * given_from_own;
    sc.centre_enu_m = centre_own;
    sc.focal_px = cam.fx;
    sc.principal_px = {cam.cx, cam.cy};
    sc.width_px = cam.width_px;
    sc.height_px = cam.height_px;
    const RenderedView img = RenderView(r.city, sc, r.scene_from_enu, light);
    std::vector<std::uint8_t> mask(static_cast<std::size_t>(img.width_px) * img.height_px, 0);
    const double x1 = o.blocks_x * o.size_m, y1 = o.blocks_y * o.size_m;
    for (std::size_t p = 0; p < mask.size(); ++p) {
      const Eigen::Vector3f& h = img.hit_scene[p];
      if (std::isfinite(h.x()) && h.x() >= 0 && h.x() < x1 && h.y() >= 0 && h.y() < y1) mask[p] = 255;
    }
    WriteBytePng((fs::path(out_dir) / (name + ".png")).string(), img.width_px, img.height_px, 3, img.rgb.data());
    WriteBytePng((fs::path(out_dir) / (name + "_mask.png")).string(), img.width_px, img.height_px, 1, mask.data());
    progress.Advance(++written, name);
  }
  progress.End();
  return written;
}

}  // namespace skyfall::synth
