#include "products/land_cover.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/format.h"
#include "core/stats.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
constexpr double kMadToSigma = 1.4826;  // robust sigma of a normal sample from its median absolute deviation
// Darker than this (sum of the bands) has no meaningful chromaticity.
constexpr double kMinBrightness = 1e-3;

std::uint8_t Code(LandCover c) { return static_cast<std::uint8_t>(c); }

// Counts of a mask over a box of half side `r` around each cell, clipped at
// the grid's edges: a row pass into 16-bit counts, then columns summed on
// the fly, so memory is 2 bytes a cell whatever the radius.
class WindowCounts {
 public:
  WindowCounts(const std::vector<std::uint8_t>& mask, int nx, int ny, int r)
      : nx_(nx), ny_(ny), r_(r), rows_(mask.size(), 0) {
    for (int row = 0; row < ny; ++row) {
      const std::uint8_t* in = &mask[static_cast<std::size_t>(row) * nx];
      std::uint16_t* out = &rows_[static_cast<std::size_t>(row) * nx];
      int count = 0;
      for (int col = 0; col < std::min(r, nx); ++col) count += in[col];
      for (int col = 0; col < nx; ++col) {
        if (col + r < nx) count += in[col + r];
        if (col - r - 1 >= 0) count -= in[col - r - 1];
        out[col] = static_cast<std::uint16_t>(count);
      }
    }
  }
  int At(int col, int row) const {
    int count = 0;
    for (int q = std::max(row - r_, 0); q <= std::min(row + r_, ny_ - 1); ++q)
      count += rows_[static_cast<std::size_t>(q) * nx_ + col];
    return count;
  }

 private:
  int nx_, ny_, r_;
  std::vector<std::uint16_t> rows_;
};

// The threshold of the vegetation vote: the objects' median excess green
// plus `sigmas` robust sigmas. Relative, because a sensor's colour balance
// shifts every roof's and crown's excess green alike.
double GreenThreshold(const std::vector<float>& green, const std::vector<std::uint8_t>& object, double sigmas) {
  std::vector<double> values;
  for (std::size_t p = 0; p < green.size(); ++p)
    if (object[p] && std::isfinite(green[p])) values.push_back(green[p]);
  if (values.empty()) return std::numeric_limits<double>::infinity();
  const double median = Median(values);
  for (double& v : values) v = std::abs(v - median);
  return median + sigmas * kMadToSigma * Median(values);
}

void Count(LandCoverMap* map) {
  for (std::uint8_t c : map->classes) {
    if (c == Code(LandCover::kGround)) ++map->ground_cells;
    if (c == Code(LandCover::kBuilding)) ++map->building_cells;
    if (c == Code(LandCover::kHighVegetation)) ++map->vegetation_cells;
    if (c == Code(LandCover::kAboveGround)) ++map->above_ground_cells;
  }
}

ClassAgreement Agreement(std::int64_t both, std::int64_t predicted, std::int64_t truth) {
  ClassAgreement a;
  a.truth_cells = truth;
  const std::int64_t either = predicted + truth - both;
  if (either > 0) a.iou = static_cast<double>(both) / either;
  if (predicted > 0) a.precision = static_cast<double>(both) / predicted;
  if (truth > 0) a.recall = static_cast<double>(both) / truth;
  return a;
}

}  // namespace

void LandCoverOptions::Check() const { CheckOptionRanges(*this, "products", "land_cover"); }

std::vector<float> ExcessGreen(const std::vector<float>& rgb) {
  std::vector<float> green(rgb.size() / 3, kNan);
  for (std::size_t p = 0; p < green.size(); ++p) {
    const double r = rgb[3 * p], g = rgb[3 * p + 1], b = rgb[3 * p + 2], sum = r + g + b;
    if (std::isfinite(sum) && sum > kMinBrightness) green[p] = static_cast<float>((2 * g - r - b) / sum);
  }
  return green;
}

std::vector<float> PlaneResidualM(const DsmGrid& dsm, int half_window_px) {
  const int nx = dsm.width_px, ny = dsm.height_px, r = half_window_px;
  std::vector<float> out(static_cast<std::size_t>(nx) * ny, kNan);
  for (int row = 0; row < ny; ++row)
    for (int col = 0; col < nx; ++col) {
      const float centre = dsm.At(col, row);
      if (!std::isfinite(centre)) continue;
      // Heights relative to the centre and offsets in pixels keep the normal
      // equations well conditioned at any ellipsoidal height.
      Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
      Eigen::Vector3d atz = Eigen::Vector3d::Zero();
      double zz = 0;
      int n = 0;
      for (int dr = -r; dr <= r; ++dr)
        for (int dc = -r; dc <= r; ++dc) {
          const int c = col + dc, q = row + dr;
          if (c < 0 || q < 0 || c >= nx || q >= ny) continue;
          const float h = dsm.At(c, q);
          if (!std::isfinite(h)) continue;
          const Eigen::Vector3d a(dc, dr, 1.0);
          const double z = static_cast<double>(h) - centre;
          ata += a * a.transpose();
          atz += a * z;
          zz += z * z;
          ++n;
        }
      if (n < 4) continue;
      const Eigen::LDLT<Eigen::Matrix3d> solve(ata);
      if (solve.info() != Eigen::Success) continue;
      const Eigen::Vector3d plane = solve.solve(atz);
      // Residual sum of squares of the least-squares fit: z'z - x'A'z.
      const double rss = std::max(zz - plane.dot(atz), 0.0);
      out[static_cast<std::size_t>(row) * nx + col] = static_cast<float>(std::sqrt(rss / n));
    }
  return out;
}

LandCoverMap ClassifyLandCover(const DsmGrid& dsm, const DsmGrid& dtm, const std::vector<float>& rgb, bool colour,
                               const LandCoverOptions& options) {
  if (dsm.width_px != dtm.width_px || dsm.height_px != dtm.height_px)
    throw Error("products", "land_cover", "the DSM and the DTM must share one grid");
  const int nx = dsm.width_px, ny = dsm.height_px;
  const std::size_t n = static_cast<std::size_t>(nx) * ny;
  LandCoverMap map;
  map.colour = colour && rgb.size() == 3 * n;
  map.classes.assign(n, Code(LandCover::kNoData));
  std::vector<std::uint8_t> object(n, 0);
  for (std::size_t p = 0; p < n; ++p) {
    const double above_m = static_cast<double>(dsm.height_m[p]) - dtm.height_m[p];
    if (!std::isfinite(above_m)) continue;
    object[p] = above_m > options.object_min_m;
    map.classes[p] = Code(object[p] ? LandCover::kAboveGround : LandCover::kGround);
  }
  if (!map.colour) {
    Count(&map);
    return map;
  }
  const std::vector<float> green = ExcessGreen(rgb);
  const int plane_px = std::max(1, static_cast<int>(std::lround(options.plane_half_window_m / dsm.gsd_m)));
  const std::vector<float> rough_m = PlaneResidualM(dsm, plane_px);
  map.green_threshold = GreenThreshold(green, object, options.green_sigmas);
  std::vector<std::uint8_t> vote(n, 0);
  for (std::size_t p = 0; p < n; ++p)
    vote[p] = object[p] && green[p] > map.green_threshold && rough_m[p] > options.min_roughness_m;
  // A majority of the object cells around decides, so that a roof's rough
  // rim or a lone green pixel does not flip a cell.
  const int vote_px = static_cast<int>(std::lround(options.vote_radius_m / dsm.gsd_m));
  const WindowCounts votes(vote, nx, ny, vote_px), objects(object, nx, ny, vote_px);
  for (int row = 0; row < ny; ++row)
    for (int col = 0; col < nx; ++col) {
      const std::size_t p = static_cast<std::size_t>(row) * nx + col;
      if (!object[p]) continue;
      const bool vegetation = 2 * votes.At(col, row) > objects.At(col, row);
      map.classes[p] = Code(vegetation ? LandCover::kHighVegetation : LandCover::kBuilding);
    }
  Count(&map);
  return map;
}

LandCoverAgreement CompareLandCover(const LandCoverMap& map, const std::vector<float>& truth_cls, int width_px,
                                    int height_px, int shift_col_px, int shift_row_px) {
  LandCoverAgreement out;
  const std::size_t n = static_cast<std::size_t>(width_px) * height_px;
  if (truth_cls.size() != n || map.classes.size() != n) return out;
  const std::array<LandCover, 3> kinds = {LandCover::kGround, LandCover::kBuilding, LandCover::kHighVegetation};
  std::array<std::int64_t, 3> both{}, predicted{}, truth{};
  std::int64_t correct = 0;
  for (int row = 0; row < height_px; ++row)
    for (int col = 0; col < width_px; ++col) {
      const int c = col + shift_col_px, r = row + shift_row_px;
      if (c < 0 || r < 0 || c >= width_px || r >= height_px) continue;
      const float t = truth_cls[static_cast<std::size_t>(row) * width_px + col];
      const std::uint8_t got = map.classes[static_cast<std::size_t>(r) * width_px + c];
      if (!std::isfinite(t) || got == Code(LandCover::kNoData)) continue;
      const int want = static_cast<int>(std::lround(t));
      bool labelled = false;
      for (std::size_t k = 0; k < kinds.size(); ++k) {
        const int code = Code(kinds[k]);
        labelled |= want == code;
        truth[k] += want == code;
        both[k] += want == code && got == code;
      }
      if (!labelled) continue;  // water, bridges, unlabelled: no class of ours to score
      for (std::size_t k = 0; k < kinds.size(); ++k) predicted[k] += got == Code(kinds[k]);
      correct += got == want;
      ++out.cells;
    }
  out.ground = Agreement(both[0], predicted[0], truth[0]);
  out.building = Agreement(both[1], predicted[1], truth[1]);
  out.vegetation = Agreement(both[2], predicted[2], truth[2]);
  if (out.cells > 0) out.overall_accuracy = static_cast<double>(correct) / out.cells;
  return out;
}

const std::map<int, std::array<std::uint8_t, 3>>& LandCoverColours() {
  static const std::map<int, std::array<std::uint8_t, 3>> colours = {
      {Code(LandCover::kAboveGround), {200, 120, 200}},
      {Code(LandCover::kGround), {170, 150, 110}},
      {Code(LandCover::kHighVegetation), {40, 150, 50}},
      {Code(LandCover::kBuilding), {220, 60, 50}}};
  return colours;
}

void WriteLandCoverCog(const std::string& path, const DsmGrid& grid, const LandCoverMap& map,
                       const std::map<std::string, std::string>& metadata) {
  CogBands bands;
  bands.descriptions = {"land_cover"};
  bands.byte_nodata = Code(LandCover::kNoData);
  bands.colour_table = LandCoverColours();
  bands.metadata = metadata;
  bands.metadata["CLASS_CODES"] =
      "0 no data, 1 above ground (building and vegetation not told apart), 2 ground, 5 high vegetation, 6 building "
      "(ASPRS)";
  WriteCog(path, grid.width_px, grid.height_px, SampleType::kByte, map.classes.data(),
           {grid.upper_left_easting_m, grid.upper_left_northing_m, grid.gsd_m, grid.epsg, std::nullopt}, bands);
}

}  // namespace skyfall
