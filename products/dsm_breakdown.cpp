#include "products/dsm_breakdown.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/format.h"
#include "core/stats.h"

namespace skyfall {
namespace {

// Running sums of one group; Finish turns them into its figures.
struct GroupSums {
  std::vector<double> abs_error_m;
  double sum_m = 0, sum_sq_m2 = 0;

  void Add(float error_m) {
    abs_error_m.push_back(std::abs(error_m));
    sum_m += error_m;
    sum_sq_m2 += static_cast<double>(error_m) * error_m;
  }

  DsmErrorGroup Finish(std::string name, int cls, int compared_cells) const {
    DsmErrorGroup g;
    g.name = std::move(name);
    g.cls = cls;
    g.cells = static_cast<int>(abs_error_m.size());
    if (g.cells == 0) return g;  // also when nothing was compared: compared_cells is 0 only then
    double abs_sum = 0;
    for (double a : abs_error_m) abs_sum += a;
    g.share = static_cast<double>(g.cells) / compared_cells;
    g.mae_m = abs_sum / g.cells;
    g.rmse_m = std::sqrt(sum_sq_m2 / g.cells);
    g.median_abs_m = Median(abs_error_m);
    g.bias_m = sum_m / g.cells;
    g.mae_part_m = abs_sum / compared_cells;
    return g;
  }
};

// Per cell, the distance [cells, centre to centre] to the nearest cell on the
// other side of the building outline (0 where the grid has no such cell).
cv::Mat DistanceAcrossOutline(const std::vector<float>& cls, int width_px, int height_px, int building_class,
                              bool from_buildings) {
  cv::Mat side(height_px, width_px, CV_8U);
  bool other_side_exists = false;
  for (int r = 0; r < height_px; ++r)
    for (int c = 0; c < width_px; ++c) {
      const bool building = ClassCodeOf(cls[static_cast<std::size_t>(r) * width_px + c]) == building_class;
      const bool inside = building == from_buildings;
      side.at<std::uint8_t>(r, c) = inside ? 255 : 0;
      other_side_exists |= !inside;
    }
  cv::Mat distance(height_px, width_px, CV_32F, cv::Scalar(0));
  if (other_side_exists) cv::distanceTransform(side, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  return distance;
}

}  // namespace

std::vector<DsmErrorGroup> DsmBreakdown::Groups() const {
  std::vector<DsmErrorGroup> groups = classes;
  groups.push_back(roof_rim);
  groups.push_back(beside_buildings);
  groups.push_back(without_high_vegetation);
  return groups;
}

void DsmBreakdownOptions::Check() const { CheckOptionRanges(*this, "dsm"); }

int ClassCodeOf(float value) {
  if (!(value >= 0.0f && value <= 255.0f)) return -1;  // NaN fails both
  return static_cast<int>(std::lround(value));
}

std::string AsprsClassName(int code) {
  if (code == -1) return "no_class";
  static const std::map<int, std::string> kNames = {
      {1, "unclassified"},     {2, "ground"},   {3, "low_vegetation"}, {4, "medium_vegetation"},
      {5, "high_vegetation"}, {6, "building"}, {7, "low_noise"},      {9, "water"},
      {17, "bridge_deck"},    {65, "unlabeled"}};  // 65: DFC2019's code for unlabeled points
  const auto it = kNames.find(code);
  return it != kNames.end() ? it->second : "class_" + std::to_string(code);
}

DsmBreakdown BreakDownDsmError(const std::vector<float>& error_m, const std::vector<float>& cls, int width_px,
                               int height_px, double gsd_m, const DsmBreakdownOptions& options) {
  options.Check();
  const std::size_t n = static_cast<std::size_t>(width_px) * height_px;
  if (width_px <= 0 || height_px <= 0 || error_m.size() != n || cls.size() != n) {
    throw Error("dsm", "breakdown",
                "error map of " + std::to_string(error_m.size()) + " cells and class raster of " +
                    std::to_string(cls.size()) + " cells on a " + std::to_string(width_px) + "x" +
                    std::to_string(height_px) + " grid");
  }
  if (!(gsd_m > 0)) throw Error("dsm", "breakdown", "GSD must be > 0, got " + FormatDouble(gsd_m));
  const cv::Mat inside = DistanceAcrossOutline(cls, width_px, height_px, options.building_class, true);
  const cv::Mat outside = DistanceAcrossOutline(cls, width_px, height_px, options.building_class, false);
  // A small tolerance keeps a rim of exactly k cells from losing its last
  // ring to rounding (distances of 1, 2 cells are exact in theory).
  const float rim_cells = static_cast<float>(options.rim_width_m / gsd_m + 1e-6);
  // Band of a distance across the outline [cells], edge_bands beyond the
  // last band; a distance of 0 means the grid has nothing across the
  // outline: beyond every band. The tolerance as for the rim.
  const double cells_per_band = options.edge_band_m / gsd_m;
  auto band_of = [&](float distance_cells) {
    if (!(distance_cells > 0)) return options.edge_bands;
    const double k = std::ceil(distance_cells / cells_per_band - 1e-6) - 1;
    return static_cast<int>(std::clamp(k, 0.0, static_cast<double>(options.edge_bands)));
  };
  std::map<int, GroupSums> by_class;
  GroupSums roof_rim, beside, roof_interior, without_high_vegetation;
  std::vector<GroupSums> roof_bands(options.edge_bands), beside_bands(options.edge_bands);
  int compared = 0;
  for (int r = 0; r < height_px; ++r)
    for (int c = 0; c < width_px; ++c) {
      const std::size_t p = static_cast<std::size_t>(r) * width_px + c;
      const float e = error_m[p];
      if (!std::isfinite(e)) continue;
      ++compared;
      const int code = ClassCodeOf(cls[p]);
      by_class[code].Add(e);
      if (code != options.high_vegetation_class) without_high_vegetation.Add(e);
      if (code == options.building_class) {
        const float in = inside.at<float>(r, c);
        if (in > 0 && in <= rim_cells) roof_rim.Add(e);
        const int k = band_of(in);
        (k < options.edge_bands ? roof_bands[k] : roof_interior).Add(e);
      } else {
        const float out = outside.at<float>(r, c);
        if (out > 0 && out <= rim_cells) beside.Add(e);
        const int k = band_of(out);
        if (k < options.edge_bands) beside_bands[k].Add(e);
      }
    }
  DsmBreakdown b;
  b.rim_width_m = options.rim_width_m;
  for (const auto& [code, sums] : by_class) b.classes.push_back(sums.Finish(AsprsClassName(code), code, compared));
  b.roof_rim = roof_rim.Finish("roof_rim", -1, compared);
  b.beside_buildings = beside.Finish("beside_buildings", -1, compared);
  b.edge_band_m = options.edge_band_m;
  for (int k = 0; k < options.edge_bands; ++k) {
    b.roof_bands.push_back(roof_bands[k].Finish("roof_band_" + std::to_string(k), -1, compared));
    b.beside_bands.push_back(beside_bands[k].Finish("beside_band_" + std::to_string(k), -1, compared));
  }
  b.roof_interior = roof_interior.Finish("roof_interior", -1, compared);
  b.without_high_vegetation = without_high_vegetation.Finish("without_high_vegetation", -1, compared);
  return b;
}

}  // namespace skyfall
