#include "core/rpc_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "core/format.h"
#include "core/rpc_terms.h"

namespace skyfall {
namespace {

struct Sample {
  double L, P, H;      // normalized ground coordinates
  double col_n, row_n; // normalized image coordinates
};

using rpc_terms::Dot;

// Solves one image coordinate: value ~= num(m) / den(m), den[0] = 1.
// With `rational` false the denominator stays 1 (a cubic polynomial).
void SolveCoordinate(const std::vector<Sample>& samples, bool row, bool rational,
                     const std::array<double, 20>& previous_den, double ridge,
                     std::array<double, 20>* num, std::array<double, 20>* den) {
  const int unknowns = rational ? 39 : 20;
  const int n = static_cast<int>(samples.size());
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n + (rational ? 19 : 0), unknowns);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(A.rows());
  for (int s = 0; s < n; ++s) {
    const Sample& x = samples[s];
    const auto m = rpc_terms::Monomials(x.L, x.P, x.H);
    const double v = row ? x.row_n : x.col_n;
    // Weighting by the previous denominator turns the linearized residual
    // (num - v*den) back into the true residual (num/den - v).
    const double w = rational ? 1.0 / Dot(previous_den, m) : 1.0;
    for (int k = 0; k < 20; ++k) A(s, k) = w * m[k];
    if (rational)
      for (int k = 1; k < 20; ++k) A(s, 19 + k) = -w * v * m[k];
    b(s) = w * v;
  }
  if (rational) {
    const double lambda = std::sqrt(ridge * n);
    for (int k = 0; k < 19; ++k) A(n + k, 20 + k) = lambda;
  }
  const Eigen::VectorXd x = A.colPivHouseholderQr().solve(b);
  num->fill(0.0);
  den->fill(0.0);
  (*den)[0] = 1.0;
  for (int k = 0; k < 20; ++k) (*num)[k] = x(k);
  if (rational)
    for (int k = 1; k < 20; ++k) (*den)[k] = x(19 + k);
}

}  // namespace

void RpcFitOptions::Check() const {
  auto need = [](bool ok, const char* field, double v) {
    if (!ok) throw Error("rpc_fit", field, FormatDouble(v) + " is out of range");
  };
  need(fit_steps_lonlat >= 4, "fit_steps_lonlat", fit_steps_lonlat);
  need(fit_steps_height >= 4, "fit_steps_height", fit_steps_height);
  need(check_steps_lonlat >= 2, "check_steps_lonlat", check_steps_lonlat);
  need(check_steps_height >= 2, "check_steps_height", check_steps_height);
  need(rational_iterations >= 0, "rational_iterations", rational_iterations);
  need(denominator_ridge >= 0 && std::isfinite(denominator_ridge), "denominator_ridge",
       denominator_ridge);
}

namespace {

// Points of the normalized cube [-1, 1]^3 as (L, P, H), height slowest. The
// check grid (`cell_centres`) sits between the fit samples.
std::vector<Eigen::Vector3d> NormalizedGrid(int steps_ll, int steps_h, bool cell_centres) {
  auto at = [&](int idx, int n) {
    return cell_centres ? -1.0 + (2.0 * idx + 1.0) / n : -1.0 + 2.0 * idx / (n - 1);
  };
  std::vector<Eigen::Vector3d> pts;
  for (int k = 0; k < steps_h; ++k)
    for (int j = 0; j < steps_ll; ++j)
      for (int i = 0; i < steps_ll; ++i) pts.emplace_back(at(i, steps_ll), at(j, steps_ll), at(k, steps_h));
  return pts;
}

// The model's ground offsets and scales: the domain's centre and half sides.
RpcModel GroundNormalization(const RpcFitDomain& d) {
  RpcModel rpc;
  rpc.lon_off = 0.5 * (d.min_lon_deg + d.max_lon_deg);
  rpc.lat_off = 0.5 * (d.min_lat_deg + d.max_lat_deg);
  rpc.height_off = 0.5 * (d.min_height_m + d.max_height_m);
  rpc.lon_scale = 0.5 * (d.max_lon_deg - d.min_lon_deg);
  rpc.lat_scale = 0.5 * (d.max_lat_deg - d.min_lat_deg);
  rpc.height_scale = 0.5 * (d.max_height_m - d.min_height_m);
  return rpc;
}

// Longitude, latitude [deg] and ellipsoidal height [m] of a normalized point.
Eigen::Vector3d Ground(const RpcModel& rpc, const Eigen::Vector3d& n) {
  return {rpc.lon_off + n.x() * rpc.lon_scale, rpc.lat_off + n.y() * rpc.lat_scale,
          rpc.height_off + n.z() * rpc.height_scale};
}

// Projects the fit grid, sets the model's image offsets and scales to the
// projections' bounding box, and returns the normalized samples.
std::vector<Sample> FitSamples(const std::function<Eigen::Vector2d(double, double, double)>& project,
                               const RpcFitOptions& options, RpcModel* rpc) {
  const auto fit_pts = NormalizedGrid(options.fit_steps_lonlat, options.fit_steps_height, false);
  std::vector<Eigen::Vector2d> image(fit_pts.size());
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (size_t s = 0; s < fit_pts.size(); ++s) {
    const Eigen::Vector3d g = Ground(*rpc, fit_pts[s]);
    image[s] = project(g.x(), g.y(), g.z());
    if (!image[s].allFinite()) throw Error("rpc_fit", "project", "returned a non-finite pixel");
    lo = lo.cwiseMin(image[s]);
    hi = hi.cwiseMax(image[s]);
  }
  rpc->samp_off = 0.5 * (lo.x() + hi.x());
  rpc->line_off = 0.5 * (lo.y() + hi.y());
  rpc->samp_scale = std::max(0.5 * (hi.x() - lo.x()), 1.0);
  rpc->line_scale = std::max(0.5 * (hi.y() - lo.y()), 1.0);
  std::vector<Sample> samples(fit_pts.size());
  for (size_t s = 0; s < fit_pts.size(); ++s) {
    samples[s] = {fit_pts[s].x(), fit_pts[s].y(), fit_pts[s].z(), (image[s].x() - rpc->samp_off) / rpc->samp_scale,
                  (image[s].y() - rpc->line_off) / rpc->line_scale};
  }
  return samples;
}

// Independent check points (between the fit samples) and their true pixels.
struct CheckSet {
  std::vector<Eigen::Vector3d> ground;
  std::vector<Eigen::Vector2d> image;

  // Largest and RMS pixel error of model `m` over the check points.
  void Evaluate(const RpcModel& m, double* max_px, double* rms_px) const {
    double worst = 0, sum2 = 0;
    for (size_t s = 0; s < ground.size(); ++s) {
      const Eigen::Vector3d& g = ground[s];
      const double e = (m.Project(g.x(), g.y(), g.z()) - image[s]).norm();
      worst = std::max(worst, e);
      sum2 += e * e;
    }
    *max_px = worst;
    *rms_px = std::sqrt(sum2 / ground.size());
  }
};

CheckSet MakeCheckSet(const std::function<Eigen::Vector2d(double, double, double)>& project,
                      const RpcFitOptions& options, const RpcModel& rpc) {
  CheckSet check;
  for (const auto& n : NormalizedGrid(options.check_steps_lonlat, options.check_steps_height, true)) {
    check.ground.push_back(Ground(rpc, n));
    check.image.push_back(project(check.ground.back().x(), check.ground.back().y(), check.ground.back().z()));
  }
  return check;
}

// Iterates the rational fit from `cubic`; keeps whichever model checks best.
void RefineRational(const std::vector<Sample>& samples, const CheckSet& check, const RpcFitOptions& options,
                    const RpcModel& cubic, RpcFitResult* best) {
  RpcModel rational = cubic;
  for (int it = 0; it < options.rational_iterations; ++it) {
    const auto prev_line_den = rational.line_den, prev_samp_den = rational.samp_den;
    SolveCoordinate(samples, true, true, prev_line_den, options.denominator_ridge, &rational.line_num,
                    &rational.line_den);
    SolveCoordinate(samples, false, true, prev_samp_den, options.denominator_ridge, &rational.samp_num,
                    &rational.samp_den);
    try {
      rational.Validate();  // refuse a denominator with a pole in the cube
    } catch (const Error&) {
      break;
    }
    double max_px, rms_px;
    check.Evaluate(rational, &max_px, &rms_px);
    if (max_px < best->max_residual_px) {
      best->rpc = rational;
      best->max_residual_px = max_px;
      best->rms_residual_px = rms_px;
      best->rational = true;
    }
  }
}

}  // namespace

RpcFitResult FitRpc(const std::function<Eigen::Vector2d(double, double, double)>& project,
                    const RpcFitDomain& d, const RpcFitOptions& options) {
  options.Check();
  if (!(d.min_lon_deg < d.max_lon_deg && d.min_lat_deg < d.max_lat_deg &&
        d.min_height_m < d.max_height_m)) {
    throw Error("rpc_fit", "domain", "is empty (min must be below max on every axis)");
  }
  RpcModel rpc = GroundNormalization(d);
  const std::vector<Sample> samples = FitSamples(project, options, &rpc);
  const CheckSet check = MakeCheckSet(project, options, rpc);

  RpcFitResult best;
  std::array<double, 20> unit_den{};
  unit_den[0] = 1.0;
  SolveCoordinate(samples, true, false, unit_den, 0, &rpc.line_num, &rpc.line_den);
  SolveCoordinate(samples, false, false, unit_den, 0, &rpc.samp_num, &rpc.samp_den);
  best.rpc = rpc;
  check.Evaluate(rpc, &best.max_residual_px, &best.rms_residual_px);
  RefineRational(samples, check, options, rpc, &best);
  // A domain astride the antimeridian may centre past 180; RPC00B offsets
  // live in [-180, 180) and Project takes longitudes modulo 360 around them.
  best.rpc.lon_off = WrapLongitudeDeg(best.rpc.lon_off);
  best.rpc.Validate();
  return best;
}

}  // namespace skyfall
