#include "products/dsm_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <opencv2/imgproc.hpp>

#include "core/atomic_file.h"
#include "core/format.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

constexpr double kColourRangeM = 3.0;  // the error map's colour scale saturates at +-3 m

// Diverging blue-white-red for v in [-1, 1]; BGR for OpenCV.
cv::Vec3b Diverging(double v) {
  v = std::clamp(v, -1.0, 1.0);
  const double a = std::abs(v);
  const auto fade = [&](double full) { return static_cast<std::uint8_t>(255 - (255 - full) * a); };
  return v < 0 ? cv::Vec3b(255, fade(40), fade(40)) : cv::Vec3b(fade(40), fade(40), 255);
}

void WritePngBgr(const cv::Mat& bgr, const std::string& path) {
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  WriteBytePng(path, rgb.cols, rgb.rows, 3, rgb.ptr<std::uint8_t>());
}

void ErrorMapPng(const DsmComparison& r, const DsmGrid& g, const std::string& path) {
  const int legend_w = 90;
  cv::Mat img(g.height_px, g.width_px + legend_w, CV_8UC3, cv::Scalar(255, 255, 255));
  for (int y = 0; y < g.height_px; ++y)
    for (int x = 0; x < g.width_px; ++x) {
      const float e = r.error_m[static_cast<size_t>(y) * g.width_px + x];
      img.at<cv::Vec3b>(y, x) = std::isfinite(e) ? Diverging(e / kColourRangeM) : cv::Vec3b(128, 128, 128);
    }
  // Legend: a vertical colour bar from +3 m (top) to -3 m, labelled.
  const int x0 = g.width_px + 10, top = 20, bottom = std::max(top + 40, g.height_px - 40);
  for (int y = top; y <= bottom; ++y) {
    const double v = 1.0 - 2.0 * (y - top) / (bottom - top);
    cv::line(img, {x0, y}, {x0 + 20, y}, cv::Scalar(Diverging(v)[0], Diverging(v)[1], Diverging(v)[2]));
  }
  const auto label = [&](const std::string& text, int y) {
    cv::putText(img, text, {x0 + 24, y + 4}, cv::FONT_HERSHEY_SIMPLEX, 0.35, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  };
  label("+3 m", top);
  label("0 m", (top + bottom) / 2);
  label("-3 m", bottom);
  cv::putText(img, "pred-gt", {g.width_px + 6, 12}, cv::FONT_HERSHEY_SIMPLEX, 0.35, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(img, "grey: none", {g.width_px + 4, bottom + 25}, cv::FONT_HERSHEY_SIMPLEX, 0.3, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  WritePngBgr(img, path);
}

void HistogramPng(const DsmComparison& r, const std::string& path) {
  constexpr int kBins = 60, kW = 640, kH = 360, kMargin = 40;
  const double lo = -kColourRangeM, hi = kColourRangeM;
  std::vector<int> bins(kBins, 0);
  for (float e : r.error_m) {
    if (!std::isfinite(e)) continue;
    const int b = std::clamp(static_cast<int>((e - lo) / (hi - lo) * kBins), 0, kBins - 1);
    ++bins[b];
  }
  const int peak = std::max(1, *std::max_element(bins.begin(), bins.end()));
  cv::Mat img(kH, kW, CV_8UC3, cv::Scalar(255, 255, 255));
  const double bw = static_cast<double>(kW - 2 * kMargin) / kBins;
  for (int b = 0; b < kBins; ++b) {
    const int h = static_cast<int>(static_cast<double>(bins[b]) / peak * (kH - 2 * kMargin));
    cv::rectangle(img, cv::Point(kMargin + static_cast<int>(b * bw), kH - kMargin - h),
                  cv::Point(kMargin + static_cast<int>((b + 1) * bw) - 1, kH - kMargin), cv::Scalar(160, 90, 40),
                  cv::FILLED);
  }
  cv::line(img, {kMargin, kH - kMargin}, {kW - kMargin, kH - kMargin}, cv::Scalar(0, 0, 0));
  for (int t = -3; t <= 3; ++t) {
    const int x = kMargin + static_cast<int>((t - lo) / (hi - lo) * (kW - 2 * kMargin));
    cv::line(img, {x, kH - kMargin}, {x, kH - kMargin + 5}, cv::Scalar(0, 0, 0));
    cv::putText(img, std::to_string(t), {x - 5, kH - kMargin + 18}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0),
                1, cv::LINE_AA);
  }
  char title[160];
  std::snprintf(title, sizeof(title), "DSM error (pred - gt - offset) [m]: MAE %.2f, RMSE %.2f, NMAD %.2f, n=%d", r.mae_m,
                r.rmse_m, r.nmad_m, r.valid_pixels);
  cv::putText(img, title, {kMargin, 22}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(img, "pixels (max " + std::to_string(peak) + ")", {4, kMargin - 6}, cv::FONT_HERSHEY_SIMPLEX, 0.35,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  WritePngBgr(img, path);
}

nlohmann::json GroupJson(const DsmErrorGroup& g) {
  nlohmann::json j = {{"name", g.name},       {"cells", g.cells},   {"share", g.share},
                      {"mae_m", g.mae_m},     {"rmse_m", g.rmse_m}, {"median_abs_m", g.median_abs_m},
                      {"bias_m", g.bias_m},   {"mae_part_m", g.mae_part_m}};
  if (g.cls >= 0) j["class"] = g.cls;
  return j;
}

// The end of a CSV row: a group's figures from `cells` on.
std::string GroupCsvFigures(const DsmErrorGroup& g) {
  char line[192];
  std::snprintf(line, sizeof(line), "%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f\n", g.cells, g.share, g.mae_m, g.rmse_m,
                g.median_abs_m, g.bias_m, g.mae_part_m);
  return line;
}

// report_by_class.csv: one row per class, then the two rim bands and every
// cell but high vegetation.
std::string BreakdownCsv(const DsmBreakdown& b) {
  std::string csv = "group,class,cells,share,mae_m,rmse_m,median_abs_m,bias_m,mae_part_m\n";
  for (const DsmErrorGroup& g : b.Groups()) csv += g.name + "," + std::to_string(g.cls) + "," + GroupCsvFigures(g);
  return csv;
}

// The edge profile's rows: the roof's bands from the outline inwards, its
// interior (no upper bound), then the bands beside the buildings outwards.
struct EdgeRow {
  const char* side;
  double from_m;
  std::optional<double> to_m;
  const DsmErrorGroup* group;
};
std::vector<EdgeRow> EdgeRows(const DsmBreakdown& b) {
  const auto bound_m = [&](std::size_t k) { return static_cast<double>(k) * b.edge_band_m; };
  std::vector<EdgeRow> rows;
  for (std::size_t k = 0; k < b.roof_bands.size(); ++k)
    rows.push_back({"roof", bound_m(k), bound_m(k + 1), &b.roof_bands[k]});
  rows.push_back({"roof", bound_m(b.roof_bands.size()), std::nullopt, &b.roof_interior});
  for (std::size_t k = 0; k < b.beside_bands.size(); ++k)
    rows.push_back({"beside", bound_m(k), bound_m(k + 1), &b.beside_bands[k]});
  return rows;
}

std::string EdgeProfileCsv(const DsmBreakdown& b) {
  std::string csv = "side,from_m,to_m,cells,share,mae_m,rmse_m,median_abs_m,bias_m,mae_part_m\n";
  for (const EdgeRow& r : EdgeRows(b)) {
    csv += std::string(r.side) + "," + FormatDouble(r.from_m) + "," + (r.to_m ? FormatDouble(*r.to_m) : "") + "," +
           GroupCsvFigures(*r.group);
  }
  return csv;
}

nlohmann::json EdgeProfileJson(const DsmBreakdown& b) {
  nlohmann::json profile = {{"band_m", b.edge_band_m}, {"roof", nlohmann::json::array()},
                            {"beside", nlohmann::json::array()}};
  for (const EdgeRow& r : EdgeRows(b)) {
    nlohmann::json j = GroupJson(*r.group);
    j["from_m"] = r.from_m;
    if (!r.to_m) {
      profile["roof_interior"] = j;
      continue;
    }
    j["to_m"] = *r.to_m;
    profile[r.side].push_back(j);
  }
  return profile;
}

}  // namespace

nlohmann::json DsmBreakdownJson(const DsmBreakdown& b) {
  nlohmann::json classes = nlohmann::json::array();
  for (const DsmErrorGroup& g : b.classes) classes.push_back(GroupJson(g));
  return {{"by_class", classes},
          {"building_rims",
           {{"rim_width_m", b.rim_width_m},
            {"roof_rim", GroupJson(b.roof_rim)},
            {"beside_buildings", GroupJson(b.beside_buildings)}}},
          {"building_edge_profile", EdgeProfileJson(b)},
          {"without_high_vegetation", GroupJson(b.without_high_vegetation)}};
}

void WriteDsmComparison(const DsmComparison& r, const DsmGrid& truth, const DsmCompareOptions& o,
                        const DsmReportInputs& in, const std::string& out_dir) {
  const fs::path dir(out_dir);
  const nlohmann::json report = {
      {"prediction", in.prediction_path}, {"truth", in.truth_path}, {"cls", in.cls_path},
      {"protocol", {{"max_shift_px", o.max_shift_px}, {"pyramid_levels", o.pyramid_levels},
                    {"mask_water", o.mask_water}, {"within_m", o.within_m}}},
      {"shift_col_px", r.shift_col_px}, {"shift_row_px", r.shift_row_px}, {"ncc", r.ncc},
      {"bias_m", r.bias_m}, {"z_offset_m", r.z_offset_m}, {"mae_m", r.mae_m},
      {"mae_at_zero_shift_m", r.mae_at_zero_shift_m}, {"rmse_m", r.rmse_m},
      {"median_abs_m", r.median_abs_m}, {"nmad_m", r.nmad_m}, {"completeness", r.completeness}, {"within_fraction", r.within_fraction},
      {"valid_pixels", r.valid_pixels}};
  nlohmann::json full = report;
  if (r.has_breakdown) {
    full.update(DsmBreakdownJson(r.breakdown));
    WriteFileAtomic((dir / "report_by_class.csv").string(), BreakdownCsv(r.breakdown));
    WriteFileAtomic((dir / "report_edge_profile.csv").string(), EdgeProfileCsv(r.breakdown));
  } else {
    // An earlier comparison's breakdown would no longer match this report.
    std::error_code ignored;
    fs::remove(dir / "report_by_class.csv", ignored);
    fs::remove(dir / "report_edge_profile.csv", ignored);
  }
  WriteFileAtomic((dir / "report.json").string(), full.dump(2) + "\n");
  char csv[512];
  std::snprintf(csv, sizeof(csv),
                "mae_m,rmse_m,median_abs_m,nmad_m,completeness,within_fraction,bias_m,shift_col_px,shift_row_px,"
                "valid_pixels,z_offset_m\n%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d,%d,%d,%.6f\n",
                r.mae_m, r.rmse_m, r.median_abs_m, r.nmad_m, r.completeness, r.within_fraction, r.bias_m,
                r.shift_col_px, r.shift_row_px, r.valid_pixels, r.z_offset_m);
  WriteFileAtomic((dir / "report.csv").string(), csv);
  // A difference in metres, not heights: no vertical reference.
  CogBands band;
  band.descriptions = {"DSM minus truth [m]"};
  WriteCog((dir / "error_map.tif").string(), truth.width_px, truth.height_px, SampleType::kFloat32, r.error_m.data(),
           {truth.upper_left_easting_m, truth.upper_left_northing_m, truth.gsd_m, truth.epsg, std::nullopt}, band);
  ErrorMapPng(r, truth, (dir / "error_map.png").string());
  HistogramPng(r, (dir / "error_histogram.png").string());
}

}  // namespace skyfall
