#include "dense/dense.h"

#include <fmt/format.h>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numeric>
#include <optional>
#include <utility>

#include "core/error.h"
#include "core/format.h"
#include "core/stats.h"
#include "dense/hole_fill.h"
#include "dense/sweep.h"

namespace skyfall {

using dense_detail::kNan;

void DenseOptions::Check() const {
  CheckOptionRanges(*this, "dense");
  fill.Check();  // what involves two of its fields
  if (!(pairs.max_angle_deg > pairs.min_angle_deg))
    throw Error("dense", "max_pair_angle_deg", "must exceed min_pair_angle_deg >= 0");
  if (!(sgm.p2 >= sgm.p1)) throw Error("dense", "sgm_p2", "must be >= sgm_p1 >= 0");
}

std::vector<DensePair> SelectDensePairs(const DenseOptions& o, const std::vector<DenseView>& views,
                                        const std::vector<DensePair>& pairs, const Eigen::Vector3d& centre) {
  std::vector<DensePair> kept;
  for (const DensePair& p : pairs) {
    if (p.a < 0 || p.b < 0 || p.a >= static_cast<int>(views.size()) || p.b >= static_cast<int>(views.size()) || p.a == p.b)
      throw Error("dense", "pairs", "pair (" + std::to_string(p.a) + ", " + std::to_string(p.b) + ") names no two views");
    if (p.verified < o.pairs.min_matches) continue;
    const Eigen::Vector3d ra = (views[p.a].camera.Centre() - centre).normalized();
    const Eigen::Vector3d rb = (views[p.b].camera.Centre() - centre).normalized();
    const double angle_deg = std::acos(std::clamp(ra.dot(rb), -1.0, 1.0)) * 180.0 / M_PI;
    if (angle_deg >= o.pairs.min_angle_deg && angle_deg <= o.pairs.max_angle_deg) kept.push_back(p);
  }
  std::stable_sort(kept.begin(), kept.end(), [](const DensePair& x, const DensePair& y) { return x.verified > y.verified; });
  if (kept.size() > static_cast<std::size_t>(o.pairs.max)) kept.resize(o.pairs.max);
  return kept;
}

namespace {

// The finest view's GSD at a point [m]: its depth over its focal length.
double FinestGsdM(const std::vector<DenseView>& views, const Eigen::Vector3d& centre_enu_m) {
  double finest_m = std::numeric_limits<double>::infinity();
  for (const DenseView& v : views) finest_m = std::min(finest_m, v.camera.PixelFootprintM(centre_enu_m));
  return finest_m;
}

}  // namespace

double AutomaticCellM(const std::vector<DenseView>& views, const Eigen::Vector3d& centre_enu_m) {
  return DenseCellForGsdM(FinestGsdM(views, centre_enu_m));
}

namespace {

using dense_detail::CellHeights;
using dense_detail::GreyImage;
using dense_detail::Projection;
using dense_detail::Sweep;

void CheckViewBuffers(const std::vector<DenseView>& views) {
  for (const DenseView& v : views)
    if (v.width_px < 2 || v.height_px < 2 || v.bands < 1 ||
        v.pixels.size() != static_cast<std::size_t>(v.width_px) * v.height_px * v.bands)
      throw Error("dense", v.name, "pixel buffer does not match " + std::to_string(v.width_px) + "x" +
                                       std::to_string(v.height_px) + "x" + std::to_string(v.bands));
}

// The grid and the sweep's heights: the tie points' horizontal box, clipped
// to the extent; heights from the tie points inside.
struct SweepPlan {
  std::size_t points_inside = 0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // mean of the tie points inside
  double z_lo = 0, z_hi = 0;
  double tie_points_z_hi = 0;          // z_hi before the probe raised it
  double finest_gsd_m = 0;             // of the views, at the tie points' centre
  bool probe_ran = false;
  std::optional<double> probe_top_m;   // the highest surface the probe found, if it ran and found one
  double step_m = 0;  // height_step_m, or coarser where the range needs more than max_heights
  int nh = 0;
  std::string note;   // why the step is coarser, when it is
};

// A range longer than max_heights steps (towers, hills) is swept with a
// coarser step rather than refused: the volume's memory stays bounded and
// the parabola fit between steps keeps sub-step heights.
void SetHeightSteps(const DenseOptions& o, const char* what, SweepPlan* plan) {
  plan->step_m = o.height_step_m;
  plan->nh = static_cast<int>(std::ceil((plan->z_hi - plan->z_lo) / plan->step_m)) + 1;
  plan->note.clear();
  if (plan->nh > o.max_heights) {
    plan->step_m = (plan->z_hi - plan->z_lo) / (o.max_heights - 1);
    plan->nh = std::min(o.max_heights, static_cast<int>(std::ceil((plan->z_hi - plan->z_lo) / plan->step_m)) + 1);
    plan->note = fmt::format("{} span {:.1f} m, more than max_heights {} steps of {:.2f} m: swept in steps of {:.3f} m",
                             what, plan->z_hi - plan->z_lo, o.max_heights, o.height_step_m, plan->step_m);
  }
}

SweepPlan PlanSweep(const DenseOptions& given, const std::vector<DenseView>& views,
                    const std::vector<Eigen::Vector3d>& all_points, const std::optional<GroundBox>& extent,
                    DenseOptions* o, HeightGrid* g) {
  SweepPlan plan;
  std::vector<double> z;
  for (const Eigen::Vector3d& p : all_points)
    if (!extent || extent->Contains(p.x(), p.y())) {
      plan.centre += p;
      z.push_back(p.z());
    }
  plan.points_inside = z.size();
  if (z.size() < 3) return plan;
  Eigen::Vector2d lo = all_points[0].head<2>(), hi = lo;
  for (const auto& p : all_points) {
    lo = lo.cwiseMin(p.head<2>());
    hi = hi.cwiseMax(p.head<2>());
  }
  if (extent) {
    lo = lo.cwiseMax(extent->min_m);
    hi = hi.cwiseMin(extent->max_m);
  }
  plan.centre /= static_cast<double>(z.size());
  plan.finest_gsd_m = FinestGsdM(views, plan.centre);
  if (given.cell_m == 0) o->cell_m = DenseCellForGsdM(plan.finest_gsd_m);
  plan.z_lo = Quantile(z, o->height_percentile) - o->height_margin_m;
  plan.z_hi = Quantile(z, 1.0 - o->height_percentile) + o->height_margin_m;
  SetHeightSteps(*o, "tie points", &plan);
  g->cell_m = o->cell_m;
  g->x0_m = lo.x();
  g->y0_m = lo.y();
  g->nx = static_cast<int>(std::floor((hi.x() - lo.x()) / o->cell_m)) + 1;
  g->ny = static_cast<int>(std::floor((hi.y() - lo.y()) / o->cell_m)) + 1;
  return plan;
}

// The views the chosen pairs use, each with its slot in the sweep's arrays.
struct ViewSlots {
  std::vector<int> used;  // view indices, ascending
  std::vector<int> slot;  // view index -> slot (-1: unused)
  std::vector<GreyImage> grey;  // per slot
  std::vector<Projection> projection;
  std::vector<Eigen::Vector3d> to_cameras;       // per slot: ENU direction from the centre to the camera
  std::vector<std::array<int, 2>> camera_pairs;  // the pairs, as slots
  // Per slot, blurred for the coarse sweeps (the range probe, the hole
  // sweep) at max(coarse_factor, 2) x the cell; empty when neither runs.
  dense_detail::CoarseViews coarse;
};

ViewSlots SlotViews(const DenseOptions& o, const std::vector<DenseView>& views, const std::vector<DensePair>& pairs,
                    const Eigen::Vector3d& centre, double finest_gsd_m) {
  ViewSlots v;
  for (const DensePair& p : pairs) {
    v.used.push_back(p.a);
    v.used.push_back(p.b);
  }
  std::sort(v.used.begin(), v.used.end());
  v.used.erase(std::unique(v.used.begin(), v.used.end()), v.used.end());
  v.slot.assign(views.size(), -1);
  for (int k : v.used) {
    v.slot[k] = static_cast<int>(v.grey.size());
    dense_detail::GreyImage grey = dense_detail::ToGrey(views[k]);
    // Cells finer than the sensor's pixels sample each pixel's noise several
    // times, so a window holds fewer independent noise values and less of
    // the noise's variance: the noise as the grid sees it scales with cell
    // over pixel (decision D-161: a 2.1 m sensor on 1 m cells, compensated
    // for the whole of it, lost 14% of its DSM). Sub-metre sensors' 0.5 m
    // cells are no finer than their pixels.
    if (finest_gsd_m > o.cell_m) grey.noise_std *= static_cast<float>(o.cell_m / finest_gsd_m);
    v.grey.push_back(std::move(grey));
    v.projection.push_back(dense_detail::ProjectionOf(views[k].camera));
    v.to_cameras.push_back(views[k].camera.Centre() - centre);
  }
  for (const DensePair& p : pairs) v.camera_pairs.push_back({v.slot[p.a], v.slot[p.b]});
  const bool hole_sweep = o.fill_holes && o.coarse.factor > 1;
  if (o.range_probe.above_m > 0 || hole_sweep)
    v.coarse = dense_detail::BlurForCoarseSweeps(v.grey, v.projection, o.cell_m, std::max(o.coarse.factor, 2), centre);
  return v;
}

// Tie points are sparse where the imagery is coarse, and a tall roof may
// hold none: the tie points' height range then ends below it and the
// sweep cannot find it (a 2 m sensor's towers came out as holes filled at
// the ground). A coarse sweep up to range_probe_above_m above that range
// looks for surfaces there, and the fine sweep's range is raised to the
// highest it finds.
void RaiseRangeToProbe(const DenseOptions& o, const HeightGrid& g, const ViewSlots& v,
                       const std::vector<DensePair>& pairs, Progress& progress, SweepPlan* plan) {
  plan->tie_points_z_hi = plan->z_hi;
  if (o.range_probe.above_m <= 0 || plan->finest_gsd_m < o.range_probe.min_gsd_m) return;
  plan->probe_ran = true;
  const Sweep from_tie_points{o, g, plan->z_lo, plan->step_m, plan->nh, pairs, v.slot, v.grey, v.projection};
  plan->probe_top_m =
      dense_detail::ProbeTopHeight(from_tie_points, v.coarse, plan->z_hi + o.range_probe.above_m, progress);
  if (!plan->probe_top_m || *plan->probe_top_m + o.height_margin_m <= plan->z_hi) return;
  plan->z_hi = *plan->probe_top_m + o.height_margin_m;
  SetHeightSteps(o, "tie points and the probe's surfaces", plan);
}

// What the steps after the sweep count, for the report.
struct DenseCounts {
  std::size_t visibility_changed = 0, measured = 0, occluded = 0, coarse = 0, floating = 0, sides_changed = 0;
  std::size_t roofs_over_unseen_ground = 0;
  std::size_t valid = 0;
  int terrain_trend_terms = 0;
};

// The sweep, and with o.visibility_pass a second one that scores each height
// only with the pairs that see it on the first surface (holes filled).
CellHeights SweepHeights(const Sweep& sweep, const ViewSlots& v, const HoleFillGrid& fill, Progress& progress,
                         DenseCounts* counts) {
  const DenseOptions& o = sweep.o;
  const HeightGrid& g = sweep.grid;
  CellHeights first = PickHeights(sweep, CostVolume(sweep, nullptr, "dense: sweeping heights", progress), progress);
  if (!o.visibility.pass) return first;
  std::vector<float> surface = first.height_m;
  const GroundModel model = GroundModelOf(surface, g.nx, g.ny, fill);
  const std::vector<std::uint8_t> occluded =
      OccludedAtGround(g, surface, model.terrain_m, v.to_cameras, v.camera_pairs, o.visibility.tolerance_m,
                       sweep.z_lo, o.fill_edge_hides);
  const std::vector<std::uint8_t> filled = FillHoles(surface, g.nx, g.ny, fill, model, &occluded);
  // Only the measured surface and the occluded ground (filled with the
  // terrain) hide what is behind them, not the seen holes' fill (D-062).
  for (std::size_t k = 0; k < sweep.Cells(); ++k)
    if (filled[k] && !occluded[k]) surface[k] = dense_detail::kNan;
  const std::vector<std::vector<float>> seen_above =
      dense_detail::SeenAbove(g, surface, v.to_cameras, sweep.z_lo, o.visibility.tolerance_m,
                              o.visibility.near_cells >= 0 ? o.visibility.near_cells : o.window_cells / 2);
  CellHeights second = PickHeights(
      sweep, CostVolume(sweep, &seen_above, "dense: sweeping heights the views see", progress), progress);
  for (std::size_t k = 0; k < sweep.Cells(); ++k)
    if (std::isfinite(second.height_m[k]) && std::isfinite(first.height_m[k]) &&
        std::abs(second.height_m[k] - first.height_m[k]) > 1.0f)
      ++counts->visibility_changed;
  return second;
}

// Holes: floating patches removed, a coarse sweep where the views see the
// ground, the fill from the terrain model, and filled cells' sides decided
// by the views (o.decide_filled_sides). Coarse heights count as filled: they
// are not measured at the grid's own scale.
void FillGridHoles(const Sweep& sweep, const ViewSlots& v, const HoleFillGrid& fill, Progress& progress,
                   HeightGrid* g, DenseCounts* counts) {
  const DenseOptions& o = sweep.o;
  const std::size_t cells = sweep.Cells();
  const GroundModel model = GroundModelOf(g->height_m, g->nx, g->ny, fill);
  counts->terrain_trend_terms = model.terrain_trend_terms;
  FloatingPatchOptions floating;
  floating.max_cells = static_cast<int>(std::lround(o.floating_patch_max_m2 / (o.cell_m * o.cell_m)));
  floating.min_rise_m = static_cast<float>(o.floating_patch_min_rise_m);
  counts->floating = RemoveFloatingPatches(g->height_m, g->nx, g->ny, model.terrain_m, floating);
  counts->measured -= counts->floating;
  const std::vector<std::uint8_t> occluded =
      OccludedAtGround(*g, g->height_m, model.terrain_m, v.to_cameras, v.camera_pairs, o.visibility.tolerance_m,
                       sweep.z_lo, o.fill_edge_hides);
  counts->occluded = static_cast<std::size_t>(std::count(occluded.begin(), occluded.end(), 1));
  std::vector<std::uint8_t> from_coarse(cells, 0);
  if (o.coarse.factor > 1) {
    const std::vector<float> coarse = dense_detail::CoarseSweepHeights(sweep, v.coarse, progress);
    for (std::size_t k = 0; k < cells; ++k)
      if (!std::isfinite(g->height_m[k]) && !occluded[k] && std::isfinite(coarse[k])) {
        g->height_m[k] = coarse[k];
        from_coarse[k] = 1;
        ++counts->coarse;
      }
  }
  const std::vector<float> measured_m = g->height_m;  // coarse heights included: they are a surface
  g->filled = FillHoles(g->height_m, g->nx, g->ny, fill, model, &occluded, &g->fill_rule);
  if (o.steps.decide_filled_sides) {
    std::vector<std::uint8_t> candidates = g->filled;
    for (std::size_t k = 0; k < cells; ++k) candidates[k] &= from_coarse[k] ? 0 : 1;
    const std::vector<float> before = g->height_m;
    const dense_detail::SidesDecided decided = dense_detail::DecideFilledSides(
        sweep, v.to_cameras, measured_m, model.terrain_m, candidates, fill.radius_cells, g->height_m, progress);
    counts->sides_changed = decided.changed;
    counts->roofs_over_unseen_ground = decided.over_unseen_ground;
    for (std::size_t k = 0; k < cells; ++k)
      if (candidates[k] && g->height_m[k] != before[k]) g->fill_rule[k] = FillRule::kSideByViews;
  }
  for (std::size_t k = 0; k < cells; ++k) {
    g->filled[k] |= from_coarse[k];
    if (from_coarse[k]) g->fill_rule[k] = FillRule::kCoarse;
  }
  g->terrain_m = model.terrain_m;
}

// Per cell, how many views of the matched pairs see its surface point: it
// lies inside the view's image and nothing of the surface hides it.
void CountSeeingViews(const Sweep& sweep, const ViewSlots& v, const std::vector<DenseView>& views, HeightGrid* g) {
  const DenseOptions& o = sweep.o;
  const std::vector<std::vector<float>> seen_above =
      dense_detail::SeenAbove(*g, g->height_m, v.to_cameras, sweep.z_lo, o.visibility.tolerance_m,
                              o.visibility.near_cells >= 0 ? o.visibility.near_cells : o.window_cells / 2);
  g->views.assign(g->height_m.size(), 0);
  for (std::size_t s = 0; s < v.used.size(); ++s) {
    const DenseView& view = views[v.used[s]];
    for (int j = 0; j < g->ny; ++j)
      for (int i = 0; i < g->nx; ++i) {
        const std::size_t k = g->Index(i, j);
        const float h = g->height_m[k];
        if (!std::isfinite(h) || h < seen_above[s][k]) continue;  // SeenAbove has the tolerance in it
        const Eigen::Vector2d px = view.camera.Project({g->x0_m + i * g->cell_m, g->y0_m + j * g->cell_m, h});
        if (px.x() < -0.5 || px.y() < -0.5 || px.x() > view.width_px - 0.5 || px.y() > view.height_px - 0.5) continue;
        g->views[k] = static_cast<std::uint8_t>(std::min(255, g->views[k] + 1));
      }
  }
}

// Each cell's colour from the most nadir view that sees it; returns how many
// cells have a height.
std::size_t ColourCells(const std::vector<DenseView>& views, const Eigen::Vector3d& centre, HeightGrid* g) {
  std::vector<int> by_elevation(views.size());
  std::iota(by_elevation.begin(), by_elevation.end(), 0);
  auto elevation = [&](int v) { return (views[v].camera.Centre() - centre).normalized().z(); };
  std::sort(by_elevation.begin(), by_elevation.end(), [&](int a, int b) { return elevation(a) > elevation(b); });
  g->rgb.assign(static_cast<std::size_t>(g->nx) * g->ny, {0, 0, 0});
  std::size_t valid = 0;
  for (int j = 0; j < g->ny; ++j)
    for (int i = 0; i < g->nx; ++i) {
      const std::size_t k = g->Index(i, j);
      if (!std::isfinite(g->height_m[k])) continue;
      ++valid;
      const Eigen::Vector3d world(g->x0_m + i * g->cell_m, g->y0_m + j * g->cell_m, g->height_m[k]);
      for (int v : by_elevation) {
        const DenseView& view = views[v];
        const Eigen::Vector2d px = view.camera.Project(world);
        const int u = static_cast<int>(std::lround(px.x())), w = static_cast<int>(std::lround(px.y()));
        if (u < 0 || w < 0 || u >= view.width_px || w >= view.height_px) continue;
        const float* p = view.pixels.data() + (static_cast<std::size_t>(w) * view.width_px + u) * view.bands;
        if (!std::isfinite(p[0])) continue;  // no data there: the next view
        for (int b = 0; b < 3; ++b)
          g->rgb[k][b] = static_cast<std::uint8_t>(std::clamp(p[std::min(b, view.bands - 1)], 0.0f, 255.0f));
        break;
      }
    }
  return valid;
}

void ReportMetrics(const DenseOptions& o, const SweepPlan& plan, const ViewSlots& v, const CellHeights& picked,
                   const DenseCounts& n, std::size_t pairs, std::size_t cells, StageReport* r) {
  const double all = static_cast<double>(cells);
  r->metrics["cell_m"] = o.cell_m;
  r->metrics["cells"] = all;
  r->metrics["heights"] = plan.nh;
  r->metrics["height_step_m"] = plan.step_m;
  r->metrics["height_min_m"] = plan.z_lo;
  r->metrics["height_max_m"] = plan.z_hi;
  r->metrics["tie_points_height_max_m"] = plan.tie_points_z_hi;
  r->metrics["finest_gsd_m"] = plan.finest_gsd_m;
  r->metrics["range_probe_ran"] = plan.probe_ran ? 1.0 : 0.0;
  if (plan.probe_top_m) r->metrics["probe_top_m"] = *plan.probe_top_m;
  r->metrics["pairs"] = static_cast<double>(pairs);
  r->metrics["views"] = static_cast<double>(v.used.size());
  // The noisiest view's sensor noise as the grid's cells sample it, as a
  // fraction of its 99th percentile grey level, and the share of its
  // variance the windows discount.
  float noise_std = 0;
  for (const dense_detail::GreyImage& grey : v.grey) noise_std = std::max(noise_std, grey.noise_std);
  r->metrics["view_noise_std_max"] = noise_std;
  r->metrics["noise_compensation"] = o.noise_compensation;
  r->metrics["valid_fraction"] = static_cast<double>(n.measured) / all;
  r->metrics["filled_fraction"] = static_cast<double>(n.valid - n.measured) / all;
  r->metrics["rejected_cost_fraction"] = 1.0 - static_cast<double>(picked.low_cost) / all;
  r->metrics["rejected_speckle_fraction"] = static_cast<double>(picked.speckles) / all;
  r->metrics["coarse_fraction"] = static_cast<double>(n.coarse) / all;
  r->metrics["floating_removed_fraction"] = static_cast<double>(n.floating) / all;
  r->metrics["occluded_fraction"] = static_cast<double>(n.occluded) / all;
  r->metrics["terrain_trend_terms"] = n.terrain_trend_terms;
  r->metrics["filled_sides_changed_fraction"] = static_cast<double>(n.sides_changed) / all;
  r->metrics["filled_roof_over_unseen_ground_fraction"] = static_cast<double>(n.roofs_over_unseen_ground) / all;
  r->metrics["visibility_changed_fraction"] = static_cast<double>(n.visibility_changed) / all;
}

}  // namespace

DenseResult RunDenseHeights(const DenseOptions& given, const std::vector<DenseView>& views,
                            const std::vector<DensePair>& pairs, const std::vector<Eigen::Vector3d>& all_points,
                            Progress& progress, const std::optional<GroundBox>& extent) {
  given.Check();
  CheckViewBuffers(views);
  DenseOptions o = given;
  Stopwatch clock;
  DenseResult result;
  result.report.stage = "dense";
  auto degenerate = [&](const std::string& why) {
    result.report.status = StageStatus::kDegenerate;
    result.report.message = why;
    result.report.seconds = clock.Seconds();
    return result;
  };
  HeightGrid& g = result.grid;
  SweepPlan plan = PlanSweep(given, views, all_points, extent, &o, &g);
  if (plan.points_inside < 3)
    return degenerate(std::to_string(plan.points_inside) + " tie points" + (extent ? " inside the tile extent" : "") +
                      ": fewer than 3, no extent or height range to sweep");
  result.pairs_used = SelectDensePairs(o, views, pairs, plan.centre);
  if (result.pairs_used.empty()) return degenerate("no image pair has enough tie points at a usable intersection angle");
  const ViewSlots v = SlotViews(o, views, result.pairs_used, plan.centre, plan.finest_gsd_m);
  const HoleFillGrid fill = o.fill.OnGrid(o.cell_m);
  RaiseRangeToProbe(o, g, v, result.pairs_used, progress, &plan);
  result.report.message = plan.note;
  const Sweep sweep{o, g, plan.z_lo, plan.step_m, plan.nh, result.pairs_used, v.slot, v.grey, v.projection};
  DenseCounts counts;
  CellHeights picked = SweepHeights(sweep, v, fill, progress, &counts);
  g.height_m = std::move(picked.height_m);
  g.cost = std::move(picked.cost);
  for (float h : g.height_m) counts.measured += std::isfinite(h) ? 1 : 0;
  g.filled.assign(sweep.Cells(), 0);
  g.fill_rule.assign(sweep.Cells(), FillRule::kMatched);
  if (o.fill_holes) {
    FillGridHoles(sweep, v, fill, progress, &g, &counts);
  } else {
    g.terrain_m = GroundModelOf(g.height_m, g.nx, g.ny, fill).terrain_m;  // the DTM, holes or not
  }
  counts.valid = ColourCells(views, plan.centre, &g);
  CountSeeingViews(sweep, v, views, &g);
  ReportMetrics(o, plan, v, picked, counts, result.pairs_used.size(), sweep.Cells(), &result.report);
  result.report.seconds = clock.Seconds();
  return result;
}

}  // namespace skyfall
