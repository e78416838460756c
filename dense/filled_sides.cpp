#include "dense/sweep.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numeric>

#include "dense/hole_fill.h"

namespace skyfall::dense_detail {
namespace {

// Scratch buffers of SupportWeightedCost, one per thread.
struct SupportScratch {
  std::vector<float> samples, distance;
  std::vector<std::uint8_t> usable;
};

// Samples view v's grey values on the window of cells around (i, j) lifted
// to `height_m` into `out` (row-major); false when a sample falls outside
// the image or is not finite.
bool SampleSupportWindow(const Sweep& s, std::size_t v, int i, int j, double height_m, float* out) {
  const HeightGrid& g = s.grid;
  const int r = s.o.support.radius_cells, w = 2 * r + 1;
  const GreyImage& image = s.grey[v];
  for (int b = -r; b <= r; ++b)
    for (int a = -r; a <= r; ++a) {
      const Eigen::Vector3d h = s.projection[v] * Eigen::Vector4d(g.x0_m + (i + a) * g.cell_m,
                                                                  g.y0_m + (j + b) * g.cell_m, height_m, 1.0);
      const double x = h.x() / h.z(), y = h.y() / h.z();
      const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
      if (!(h.z() > 0) || x0 < 0 || y0 < 0 || x0 + 1 >= image.width || y0 + 1 >= image.height) return false;
      const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
      const float* p = image.values.data() + static_cast<std::size_t>(y0) * image.width + x0;
      const float top = p[0] + fx * (p[1] - p[0]);
      const float bottom = p[image.width] + fx * (p[image.width + 1] - p[image.width]);
      const float value = top + fy * (bottom - top);
      if (!std::isfinite(value)) return false;
      out[(b + r) * w + (a + r)] = value;
    }
  return true;
}

// One pair's cost on the window: 1 - NCC with each window cell weighted by
// exp(-(|a - a_centre| + |b - b_centre|) / (2 sigma) - distance / R), the
// mean of its grey differences from the centre in the two views (Yoon and
// Kweon's weights from both images), truncated at `trunc`, also where a
// view's weighted window is too plain to correlate.
float PairSupportCost(const Sweep& s, const float* a, const float* b, const float* distance, float trunc) {
  const int r = s.o.support.radius_cells, n = (2 * r + 1) * (2 * r + 1);
  const float a_centre = a[n / 2], b_centre = b[n / 2];
  const float inv_two_sigma = static_cast<float>(0.5 / s.o.support.grey_sigma);
  float sw = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  for (int q = 0; q < n; ++q) {
    const float w = std::exp(-(std::abs(a[q] - a_centre) + std::abs(b[q] - b_centre)) * inv_two_sigma - distance[q]);
    const float wa = w * a[q], wb = w * b[q];
    sw += w;
    sa += wa;
    sb += wb;
    saa += wa * a[q];
    sbb += wb * b[q];
    sab += wa * b[q];
  }
  const float inv_w = 1.0f / sw;
  const float mean_a = sa * inv_w, mean_b = sb * inv_w;
  const float var_a = saa * inv_w - mean_a * mean_a, var_b = sbb * inv_w - mean_b * mean_b;
  const float min_var = static_cast<float>(s.o.min_std * s.o.min_std);
  if (!(var_a > min_var) || !(var_b > min_var)) return trunc;
  const float covariance = sab * inv_w - mean_a * mean_b;
  return std::min(trunc, 1.0f - covariance / std::sqrt(var_a * var_b));
}

// One candidate height of one cell scored with adaptive support weights:
// every view that sees the point (all views without `seen_above`) is
// sampled on the (2R+1)^2 window of cells lifted to `height_m`; each pair
// of views that both see it scores PairSupportCost, averaged as the masked
// sweep does. NaN when no view sees the point.
float SupportWeightedCost(const Sweep& s, const std::vector<std::vector<float>>* seen_above, int i, int j,
                          double height_m, SupportScratch& t) {
  const int r = s.o.support.radius_cells, w = 2 * r + 1, n = w * w;
  const std::size_t views = s.grey.size();
  const std::size_t centre_cell = s.grid.Index(i, j);
  t.samples.resize(views * n);
  t.usable.assign(views, 0);
  bool any_usable = false;
  for (std::size_t v = 0; v < views; ++v) {
    if (seen_above && height_m < (*seen_above)[v][centre_cell]) continue;
    t.usable[v] = SampleSupportWindow(s, v, i, j, height_m, t.samples.data() + v * n) ? 1 : 0;
    any_usable = any_usable || t.usable[v];
  }
  if (!any_usable) return kNan;
  if (t.distance.size() != static_cast<std::size_t>(n)) {
    t.distance.resize(n);
    for (int b = -r; b <= r; ++b)
      for (int a = -r; a <= r; ++a)
        t.distance[(b + r) * w + (a + r)] = std::sqrt(static_cast<float>(a * a + b * b)) / static_cast<float>(r);
  }
  const float trunc = static_cast<float>(s.o.cost_truncation);
  float sum = 0, count = 0;
  for (const DensePair& p : s.pairs) {
    const int va = s.slot[p.a], vb = s.slot[p.b];
    if (!t.usable[va] || !t.usable[vb]) continue;
    count += 1;
    sum += PairSupportCost(s, t.samples.data() + static_cast<std::size_t>(va) * n,
                           t.samples.data() + static_cast<std::size_t>(vb) * n, t.distance.data(), trunc);
  }
  // The visibility pass's prior, as if prior_pairs more of the other pairs
  // had added the truncation cost, here at most the other pairs there are:
  // with a single pair it put every side's cost at (c + 1.6) / 3 >= 0.53,
  // against max_cost 0.55, and no filled cell of a stereo pair could change
  // side (decision D-142). The sweep keeps the whole prior (D-140).
  const float other_pairs = static_cast<float>(s.pairs.size()) - 1.0f;
  const float prior = seen_above ? std::min(static_cast<float>(s.o.visibility.prior_pairs), other_pairs) : 0.0f;
  return count + prior > 0 ? (sum + prior * trunc) / (count + prior) : trunc;
}

}  // namespace

// DenseOptions::decide_filled_sides: each filled cell (`candidates`) is
// scored (SupportWeightedCost) at the ground (`terrain_m`) and at a raised
// height: its fill where that stands more than step_min_m above the
// ground, else the lowest measured height raised that much within
// `reach_cells` (then 4 x reach_cells) of it. The cell takes the other side
// where that side's cost is at most max_cost and step_cost_margin below its
// fill's, and where a cell filled at the ground has no measured ground
// within step_reach_cells: there the roof's side wins by the windows'
// fattening, as beside any step. Where no view can score the ground, a cell
// filled at the ground takes the roof if that costs at most
// steps.unseen_ground_roof_cost; otherwise a side no view can score
// decides nothing.
// Views count where they see the point past the measured surface
// (`measured_m`; holes hide nothing), near cells excepted as in the
// visibility pass. Returns how many cells changed side, and how many of
// them took the roof over ground no view sees.
SidesDecided DecideFilledSides(const Sweep& s, const std::vector<Eigen::Vector3d>& to_cameras,
                               const std::vector<float>& measured_m,
                               const std::vector<float>& terrain_m, const std::vector<std::uint8_t>& candidates,
                               int reach_cells, std::vector<float>& height_m, Progress& progress) {
  const HeightGrid& g = s.grid;
  const float step_min = static_cast<float>(s.o.steps.min_m);
  const float max_cost = static_cast<float>(s.o.max_cost), margin = static_cast<float>(s.o.steps.cost_margin);
  const float unseen_roof_cost = static_cast<float>(s.o.steps.unseen_ground_roof_cost);
  // The measured heights raised above the ground, and their lowest within
  // the two reaches (the fill's first and largest, 5 and 20 m by default).
  std::vector<float> raised(measured_m.size(), kNan);
  for (std::size_t k = 0; k < raised.size(); ++k)
    if (measured_m[k] > terrain_m[k] + step_min) raised[k] = measured_m[k];
  const std::vector<float> raised_near = MinFilter(raised, g.nx, g.ny, reach_cells, WindowEdge::kClip);
  const std::vector<float> raised_far = MinFilter(raised, g.nx, g.ny, 4 * reach_cells, WindowEdge::kClip);
  // Measured ground within the step's reach: beside it a roof hypothesis
  // is the windows' fattening again.
  std::vector<float> ground_cells(measured_m.size(), kNan);
  for (std::size_t k = 0; k < ground_cells.size(); ++k)
    if (std::abs(measured_m[k] - terrain_m[k]) <= step_min) ground_cells[k] = 0.0f;
  const std::vector<float> ground_near =
      MinFilter(ground_cells, g.nx, g.ny, s.o.steps.reach_cells, WindowEdge::kClip);
  const std::vector<std::vector<float>> seen_above =
      SeenAbove(g, measured_m, to_cameras, s.z_lo, s.o.visibility.tolerance_m,
                s.o.visibility.near_cells >= 0 ? s.o.visibility.near_cells : s.o.window_cells / 2);
  progress.Begin("dense: deciding filled cells between ground and roof", g.ny);
  std::atomic<int> rows_done{0};
  std::atomic<std::size_t> changed{0}, over_unseen_ground{0};
  tbb::enumerable_thread_specific<SupportScratch> scratch;
  const std::vector<float> before = height_m;
  tbb::parallel_for(0, g.ny, [&](int j) {
    SupportScratch& t = scratch.local();
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = g.Index(i, j);
      if (!candidates[k] || !std::isfinite(terrain_m[k]) || !std::isfinite(before[k])) continue;
      const bool filled_raised = before[k] > terrain_m[k] + step_min;
      if (!filled_raised && std::isfinite(ground_near[k])) continue;
      const float ground = terrain_m[k];
      const float roof = filled_raised ? before[k] : std::isfinite(raised_near[k]) ? raised_near[k] : raised_far[k];
      if (!std::isfinite(roof)) continue;
      const float cost_ground = SupportWeightedCost(s, &seen_above, i, j, ground, t);
      const float cost_roof = SupportWeightedCost(s, &seen_above, i, j, roof, t);
      if (!std::isfinite(cost_roof)) continue;
      if (!std::isfinite(cost_ground)) {
        // No view sees the ground here: a roof that matches well is the
        // surface, else the ground stays (there is nothing to weigh it against).
        if (!filled_raised && cost_roof <= unseen_roof_cost) {
          height_m[k] = roof;
          ++changed;
          ++over_unseen_ground;
        }
        continue;
      }
      const float other = filled_raised ? cost_ground : cost_roof, own = filled_raised ? cost_roof : cost_ground;
      if (other > max_cost || own - other < margin) continue;
      height_m[k] = filled_raised ? ground : roof;
      ++changed;
    }
    progress.Advance(++rows_done, "");
  });
  progress.End();
  return {changed, over_unseen_ground};
}

}  // namespace skyfall::dense_detail
