#include "products/run_report.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "splat/ply.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double NumberOrNaN(const nlohmann::json& j, const char* key) {
  return j.contains(key) && j.at(key).is_number() ? j.at(key).get<double>() : kNaN;
}

// One curve on the plot: y values scaled into the plot box.
void DrawCurve(cv::Mat& img, const std::vector<RunPoint>& pts, double RunPoint::*field, double x_max, double y_min,
               double y_max, const cv::Scalar& colour, const cv::Rect& box) {
  cv::Point prev(-1, -1);
  for (const RunPoint& p : pts) {
    const double y = p.*field;
    if (!std::isfinite(y)) continue;
    const cv::Point q(box.x + static_cast<int>(p.elapsed_s / x_max * box.width),
                      box.y + box.height - static_cast<int>((y - y_min) / (y_max - y_min) * box.height));
    if (prev.x >= 0) cv::line(img, prev, q, colour, 2, cv::LINE_AA);
    cv::circle(img, q, 3, colour, cv::FILLED, cv::LINE_AA);
    prev = q;
  }
}

void Range(const std::vector<RunPoint>& pts, double RunPoint::*field, double* lo, double* hi) {
  *lo = std::numeric_limits<double>::infinity();
  *hi = -*lo;
  for (const RunPoint& p : pts)
    if (std::isfinite(p.*field)) {
      *lo = std::min(*lo, p.*field);
      *hi = std::max(*hi, p.*field);
    }
  if (!(*lo <= *hi)) *lo = 0, *hi = 1;
  const double pad = std::max(1e-3, 0.1 * (*hi - *lo));
  *lo -= pad;
  *hi += pad;
}

}  // namespace

std::vector<RunPoint> EvaluateRun(const std::string& run_dir, const AoiCatalog& catalog, const DsmCompareOptions& o) {
  const fs::path dir(run_dir);
  const std::string report_path = (dir / "train_report.json").string();
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(ReadTextFile(report_path));
  } catch (const nlohmann::json::exception& e) {
    throw Error("report", report_path, std::string("not valid JSON: ") + e.what());
  }
  std::vector<RunPoint> out;
  for (const auto& s : doc.at("series")) {
    RunPoint p;
    p.iteration = s.at("iteration").get<int>();
    p.elapsed_s = NumberOrNaN(s, "elapsed_s");
    p.loss = NumberOrNaN(s, "loss");
    p.psnr_test_db = NumberOrNaN(s, "psnr_test_db");
    p.gaussians = NumberOrNaN(s, "gaussians");
    p.dsm_mae_m = p.dsm_rmse_m = kNaN;
    out.push_back(p);
  }
  if (!catalog.truth) return out;
  const TruthDsm truth = ReadTruthDsm(*catalog.truth);
  for (RunPoint& p : out) {
    const fs::path snapshot = dir / "checkpoints" / "snapshots" / ("scene_" + std::to_string(p.iteration) + ".ply");
    if (!fs::exists(snapshot)) continue;
    DsmGrid pred;
    const DsmComparison c =
        CompareSceneWithTruth(ReadGaussiansPly(snapshot.string()), catalog.enu_origin, *catalog.truth, truth, o, &pred);
    p.dsm_mae_m = c.mae_m;
    p.dsm_rmse_m = c.rmse_m;
  }
  return out;
}

void WriteRunReport(const std::vector<RunPoint>& pts, const std::string& out_dir) {
  const fs::path dir(out_dir);
  std::string csv = "iteration,elapsed_s,loss,psnr_test_db,gaussians,dsm_mae_m,dsm_rmse_m\n";
  for (const RunPoint& p : pts) {
    char line[256];
    std::snprintf(line, sizeof(line), "%d,%.3f,%.6f,%.4f,%.0f,%.4f,%.4f\n", p.iteration, p.elapsed_s, p.loss,
                  p.psnr_test_db, p.gaussians, p.dsm_mae_m, p.dsm_rmse_m);
    csv += line;
  }
  WriteFileAtomic((dir / "error_vs_time.csv").string(), csv);

  constexpr int kW = 800, kH = 420;
  const cv::Rect box(70, 40, kW - 140, kH - 100);
  cv::Mat img(kH, kW, CV_8UC3, cv::Scalar(255, 255, 255));
  cv::rectangle(img, box, cv::Scalar(0, 0, 0));
  double x_max = 1;
  for (const RunPoint& p : pts)
    if (std::isfinite(p.elapsed_s)) x_max = std::max(x_max, p.elapsed_s);
  double mae_lo, mae_hi, psnr_lo, psnr_hi;
  Range(pts, &RunPoint::dsm_mae_m, &mae_lo, &mae_hi);
  Range(pts, &RunPoint::psnr_test_db, &psnr_lo, &psnr_hi);
  const cv::Scalar red(40, 40, 200), blue(180, 90, 30), black(0, 0, 0);
  DrawCurve(img, pts, &RunPoint::dsm_mae_m, x_max, mae_lo, mae_hi, red, box);
  DrawCurve(img, pts, &RunPoint::psnr_test_db, x_max, psnr_lo, psnr_hi, blue, box);
  auto text = [&](const std::string& s, cv::Point at, const cv::Scalar& c) {
    cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, 0.42, c, 1, cv::LINE_AA);
  };
  for (int k = 0; k <= 4; ++k) {
    const int y = box.y + box.height - k * box.height / 4;
    char a[32], b[32], t[32];
    std::snprintf(a, sizeof(a), "%.2f", mae_lo + (mae_hi - mae_lo) * k / 4);
    std::snprintf(b, sizeof(b), "%.1f", psnr_lo + (psnr_hi - psnr_lo) * k / 4);
    text(a, {box.x - 50, y + 4}, red);
    text(b, {box.x + box.width + 8, y + 4}, blue);
    std::snprintf(t, sizeof(t), "%.0f", x_max * k / 4);
    text(t, {box.x + k * box.width / 4 - 10, box.y + box.height + 18}, black);
  }
  text("elapsed seconds", {box.x + box.width / 2 - 50, kH - 20}, black);
  text("DSM MAE [m]", {4, 25}, red);
  text("held-out PSNR [dB]", {kW - 160, 25}, blue);
  cv::Mat rgb;
  cv::cvtColor(img, rgb, cv::COLOR_BGR2RGB);
  WriteBytePng((dir / "error_vs_time.png").string(), rgb.cols, rgb.rows, 3, rgb.ptr<std::uint8_t>());
}

std::vector<PixelBox> PlaceLabels(const std::vector<std::array<int, 2>>& anchors,
                                  const std::vector<std::array<int, 2>>& sizes, const std::vector<PixelBox>& obstacles,
                                  const PixelBox& bounds, int gap_px) {
  if (anchors.size() != sizes.size()) throw Error("report", "labels", "one size per anchor is needed");
  std::vector<PixelBox> placed;
  placed.reserve(anchors.size());
  auto free = [&](const PixelBox& b) {
    if (!b.Inside(bounds)) return false;
    for (const PixelBox& o : obstacles)
      if (b.Overlaps(o)) return false;
    for (const PixelBox& o : placed)
      if (b.Overlaps(o)) return false;
    return true;
  };
  // Vertical steps of a label height, nearest first, far enough for a
  // crowd of every label at one point.
  const int max_steps = static_cast<int>(anchors.size());
  for (std::size_t k = 0; k < anchors.size(); ++k) {
    const auto [x, y] = anchors[k];
    const auto [w, h] = sizes[k];
    const PixelBox level_right{x + gap_px, y - h / 2, w, h};
    PixelBox chosen = level_right;
    bool found = false;
    for (int step = 0; step <= max_steps && !found; ++step)
      for (int sign : {1, -1}) {
        if (step == 0 && sign < 0) continue;
        const int dy = sign * step * h;
        for (const int bx : {x + gap_px, x - gap_px - w}) {
          const PixelBox b{bx, y - h / 2 + dy, w, h};
          if (free(b)) {
            chosen = b;
            found = true;
            break;
          }
        }
        if (found) break;
      }
    placed.push_back(chosen);
  }
  return placed;
}

NiceAxis NiceAxisOf(double lo, double hi, int max_ticks) {
  if (!(hi > lo)) hi = lo + 1;
  // Three ticks always suffice: a step at least the range puts one tick at
  // or below lo, at most one between, and one at or above hi.
  max_ticks = std::max(max_ticks, 3);
  const double raw = (hi - lo) / (max_ticks - 1);
  NiceAxis axis;
  for (double decade = std::pow(10.0, std::floor(std::log10(raw)));; decade *= 10.0)
    for (double m : {1.0, 2.0, 2.5, 5.0}) {
      axis.step = m * decade;
      axis.lo = std::floor(lo / axis.step + 1e-9) * axis.step;
      axis.hi = std::ceil(hi / axis.step - 1e-9) * axis.step;
      if (std::lround((axis.hi - axis.lo) / axis.step) + 1 <= max_ticks) return axis;
    }
}

int NiceAxis::Decimals() const {
  int decimals = 0;
  while (decimals < 6 && std::abs(step * std::pow(10.0, decimals) - std::round(step * std::pow(10.0, decimals))) > 1e-6)
    ++decimals;
  return decimals;
}

namespace {

const cv::Scalar kBlack(0, 0, 0), kHeldOut(200, 90, 30), kTuned(150, 150, 150), kTarget(60, 160, 60);
constexpr int kMarkerPx = 6;

// The chart of MAE against run time: its image, plot box and axes.
struct ScenesChart {
  static constexpr int kW = 900, kH = 520;
  cv::Mat img{kH, kW, CV_8UC3, cv::Scalar(255, 255, 255)};
  cv::Rect box{70, 40, kW - 110, kH - 100};
  NiceAxis x_axis, y_axis;

  cv::Point At(double seconds, double mae) const {
    return cv::Point(box.x + static_cast<int>((seconds - x_axis.lo) / (x_axis.hi - x_axis.lo) * box.width),
                     box.y + box.height - static_cast<int>(mae / y_axis.hi * box.height));
  }
  void Text(const std::string& s, cv::Point p, const cv::Scalar& c) {
    cv::putText(img, s, p, cv::FONT_HERSHEY_SIMPLEX, 0.42, c, 1, cv::LINE_AA);
  }
};

// The time axis starts at 0 unless every run took more than half the
// longest: then at a round number below the shortest, so runs of similar
// length do not crowd into one corner. Both axes end on round ticks with
// room beyond the last point.
void ChooseAxes(const std::vector<ScenePoint>& scenes, ScenesChart* chart) {
  double x_min = std::numeric_limits<double>::infinity(), x_max = 1, y_max = 0.5;
  for (const ScenePoint& s : scenes) {
    if (std::isfinite(s.seconds)) {
      x_min = std::min(x_min, s.seconds);
      x_max = std::max(x_max, s.seconds);
    }
    if (std::isfinite(s.mae_m)) y_max = std::max(y_max, s.mae_m);
    if (std::isfinite(s.dense_mae_m)) y_max = std::max(y_max, s.dense_mae_m);
  }
  const bool from_zero = !(std::isfinite(x_min) && x_min > 0.5 * x_max);
  chart->x_axis = NiceAxisOf(from_zero ? 0.0 : 0.9 * x_min, 1.05 * x_max, 6);
  chart->y_axis = NiceAxisOf(0.0, 1.1 * y_max, 8);
}

// The accuracy target lines (1.5 m required, 1.0 m goal) for reference.
void DrawTargets(ScenesChart* chart) {
  for (double line : {1.0, 1.5}) {
    if (line > chart->y_axis.hi) continue;
    const int y = chart->At(0, line).y;
    cv::line(chart->img, {chart->box.x, y}, {chart->box.x + chart->box.width, y}, kTarget, 1, cv::LINE_AA);
    chart->Text(line == 1.0 ? "1.0 m" : "1.5 m", {chart->box.x + chart->box.width - 45, y - 4}, kTarget);
  }
}

// Draws each scene's points; returns where its name should go and what the
// names must not cover.
struct SceneLabels {
  std::vector<PixelBox> markers;
  std::vector<std::array<int, 2>> anchors, sizes;
  std::vector<int> glyph_heights;  // above the text's baseline [px]
  std::vector<const ScenePoint*> labelled;
};

SceneLabels DrawPoints(const std::vector<ScenePoint>& scenes, ScenesChart* chart) {
  SceneLabels l;
  auto marker = [&](cv::Point p) { l.markers.push_back({p.x - kMarkerPx, p.y - kMarkerPx, 2 * kMarkerPx, 2 * kMarkerPx}); };
  for (const ScenePoint& s : scenes) {
    const cv::Scalar colour = s.tuned_on ? kTuned : kHeldOut;
    if (std::isfinite(s.dense_mae_m) && std::isfinite(s.seconds)) {
      cv::circle(chart->img, chart->At(s.seconds, s.dense_mae_m), kMarkerPx, colour, 1, cv::LINE_AA);
      marker(chart->At(s.seconds, s.dense_mae_m));
      if (std::isfinite(s.mae_m))
        cv::line(chart->img, chart->At(s.seconds, s.dense_mae_m), chart->At(s.seconds, s.mae_m), colour, 1);
    }
    if (std::isfinite(s.mae_m) && std::isfinite(s.seconds)) {
      const cv::Point p = chart->At(s.seconds, s.mae_m);
      cv::circle(chart->img, p, kMarkerPx, colour, cv::FILLED, cv::LINE_AA);
      marker(p);
      int baseline = 0;
      const cv::Size size = cv::getTextSize(s.scene, cv::FONT_HERSHEY_SIMPLEX, 0.42, 1, &baseline);
      l.anchors.push_back({p.x, p.y});
      l.sizes.push_back({size.width, size.height + baseline + 2});
      l.glyph_heights.push_back(size.height);
      l.labelled.push_back(&s);
    }
  }
  return l;
}

void DrawLabels(const SceneLabels& l, ScenesChart* chart) {
  const cv::Rect& box = chart->box;
  const std::vector<PixelBox> labels =
      PlaceLabels(l.anchors, l.sizes, l.markers, {box.x, box.y, box.width, box.height}, kMarkerPx + 3);
  for (std::size_t k = 0; k < labels.size(); ++k) {
    const PixelBox& b = labels[k];
    const cv::Scalar colour = l.labelled[k]->tuned_on ? kTuned : kHeldOut;
    const std::array<int, 2>& a = l.anchors[k];
    // A leader line where the label had to move off its point's level.
    if (std::abs(b.y + b.height / 2 - a[1]) > b.height / 2)
      cv::line(chart->img, {a[0], a[1]}, {b.x < a[0] ? b.x + b.width : b.x, b.y + b.height / 2}, colour, 1,
               cv::LINE_AA);
    chart->Text(l.labelled[k]->scene, {b.x, b.y + 1 + l.glyph_heights[k]}, colour);
  }
}

std::string TickLabel(const NiceAxis& axis, double v) {
  char s[32];
  std::snprintf(s, sizeof(s), "%.*f", axis.Decimals(), v);
  return std::string(s);
}

std::vector<double> Ticks(const NiceAxis& axis) {
  std::vector<double> v;
  const long n = std::lround((axis.hi - axis.lo) / axis.step);
  for (long i = 0; i <= n; ++i) v.push_back(axis.lo + static_cast<double>(i) * axis.step);
  return v;
}

void DrawAxes(ScenesChart* chart) {
  const cv::Rect& box = chart->box;
  for (double v : Ticks(chart->y_axis)) {
    const int y = chart->At(chart->x_axis.lo, v).y;
    cv::line(chart->img, {box.x - 4, y}, {box.x, y}, kBlack, 1);
    chart->Text(TickLabel(chart->y_axis, v), {box.x - 42, y + 4}, kBlack);
  }
  for (double v : Ticks(chart->x_axis)) {
    const int x = chart->At(v, 0).x;
    cv::line(chart->img, {x, box.y + box.height}, {x, box.y + box.height + 4}, kBlack, 1);
    chart->Text(TickLabel(chart->x_axis, v), {x - 10, box.y + box.height + 18}, kBlack);
  }
  chart->Text("whole run [s]", {box.x + box.width - 90, box.y + box.height + 34}, kBlack);
  chart->Text("DSM MAE [m]: filled = trained scene, open = dense heights alone; grey = tuned on",
              {box.x, ScenesChart::kH - 8}, kBlack);
  chart->Text("DSM MAE [m]", {4, 25}, kBlack);
}

}  // namespace

void WriteScenesPlot(const std::vector<ScenePoint>& scenes, const std::string& png_path) {
  ScenesChart chart;
  cv::rectangle(chart.img, chart.box, kBlack);
  ChooseAxes(scenes, &chart);
  DrawTargets(&chart);
  DrawLabels(DrawPoints(scenes, &chart), &chart);
  DrawAxes(&chart);
  cv::Mat rgb;
  cv::cvtColor(chart.img, rgb, cv::COLOR_BGR2RGB);
  WriteBytePng(png_path, rgb.cols, rgb.rows, 3, rgb.ptr<std::uint8_t>());
}

}  // namespace skyfall
