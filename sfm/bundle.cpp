#include "sfm/bundle.h"

#include <ceres/ceres.h>
#include <Eigen/Eigenvalues>

#include "core/error.h"
#include "core/format.h"

namespace skyfall {
namespace {

struct ProjectionCost {
  const PinholeCamera* camera;
  Eigen::Vector2d pixel;
  template <typename T>
  bool operator()(const T* offset, const T* point, T* residual) const {
    const Eigen::Matrix3d& R = camera->cam_from_world_rotation;
    const Eigen::Vector3d& t = camera->cam_from_world_translation;
    T c[3];
    for (int r = 0; r < 3; ++r) c[r] = T(R(r, 0)) * point[0] + T(R(r, 1)) * point[1] + T(R(r, 2)) * point[2] + T(t(r));
    const T xn = c[0] / c[2], yn = c[1] / c[2];
    residual[0] = T(camera->fx) * xn + T(camera->skew) * yn + T(camera->cx) + offset[0] - T(pixel.x());
    residual[1] = T(camera->fy) * yn + T(camera->cy) + offset[1] - T(pixel.y());
    return true;
  }
};

struct OffsetPrior {
  double inverse_sigma;
  template <typename T>
  bool operator()(const T* offset, T* residual) const {
    residual[0] = offset[0] * T(inverse_sigma);
    residual[1] = offset[1] * T(inverse_sigma);
    return true;
  }
};

}  // namespace

void BundleOptions::Check() const { CheckOptionRanges(*this, "bundle"); }

BundleSummary RunBundleAdjustment(BundleProblem* bp, const BundleOptions& options) {
  options.Check();
  ceres::Problem problem;
  for (size_t t = 0; t < bp->tracks.size(); ++t) {
    for (const Observation& o : bp->tracks[t]) {
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<ProjectionCost, 2, 2, 3>(
                                   new ProjectionCost{&bp->cameras[o.image], o.pixel}),
                               new ceres::HuberLoss(options.huber_px), bp->offsets_px[o.image].data(),
                               bp->points[t].data());
    }
  }
  const bool anchored = bp->anchor_image >= 0 && bp->anchor_image < static_cast<int>(bp->offsets_px.size()) &&
                        problem.HasParameterBlock(bp->offsets_px[bp->anchor_image].data());
  if (anchored) problem.SetParameterBlockConstant(bp->offsets_px[bp->anchor_image].data());
  for (size_t i = 0; i < bp->offsets_px.size(); ++i) {
    if (!bp->image_used[i] || !problem.HasParameterBlock(bp->offsets_px[i].data())) continue;
    // With an anchor the priors stay on the others: holding one image's 2D
    // offset fixes the shift across its image plane, not the shift along its
    // line of sight (mostly height), which only the priors pin.
    if (anchored && static_cast<int>(i) == bp->anchor_image) continue;
    if (!bp->gauge_image.empty() && !bp->gauge_image[i]) continue;
    // Cauchy: an image with a large pointing error (tens of px happen) does
    // not drag the others' offsets; the majority fixes the gauge.
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<OffsetPrior, 2, 2>(
                                 new OffsetPrior{1.0 / options.offset_prior_sigma_px}),
                             new ceres::CauchyLoss(1.0), bp->offsets_px[i].data());
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_SCHUR;
  solver.max_num_iterations = options.max_iterations;
  solver.num_threads = 1;  // one thread keeps the sums in one order: identical reruns
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  BundleSummary out;
  out.iterations = static_cast<int>(summary.iterations.size());
  out.initial_cost = summary.initial_cost;
  out.final_cost = summary.final_cost;
  out.converged = summary.termination_type == ceres::CONVERGENCE;
  return out;
}

std::vector<double> ReprojectionErrors(const BundleProblem& bp) {
  std::vector<double> errors;
  for (size_t t = 0; t < bp.tracks.size(); ++t) {
    for (const Observation& o : bp.tracks[t]) {
      const Eigen::Vector2d p = bp.cameras[o.image].Project(bp.points[t]) + bp.offsets_px[o.image];
      errors.push_back((p - o.pixel).norm());
    }
  }
  return errors;
}

namespace {
// Smallest over largest eigenvalue of sum P_i^T P_i that MoveToGaugeAverage
// accepts: 1e-3 is two views about 2 deg apart (the eigenvalue of the height
// grows with the square of the angle between the rays).
constexpr double kGaugeMinConditioning = 1e-3;
}  // namespace

double MoveToGaugeAverage(BundleProblem* bp) {
  if (bp->gauge_image.empty() || bp->points.empty()) return 0.0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : bp->points) centre += p;
  centre /= static_cast<double>(bp->points.size());
  // d(pixel)/d(scene point) at the scene's centre, by central differences
  // over 1 m: a satellite's projection is affine to far below a pixel there.
  std::vector<Eigen::Matrix<double, 2, 3>> jacobians(bp->offsets_px.size());
  for (std::size_t i = 0; i < jacobians.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d h = Eigen::Vector3d::Unit(k);
      jacobians[i].col(k) = 0.5 * (bp->cameras[i].Project(centre + h) - bp->cameras[i].Project(centre - h));
    }
  }
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < bp->offsets_px.size(); ++i) {
    if (!bp->gauge_image[i] || !bp->image_used[i]) continue;
    normal += jacobians[i].transpose() * jacobians[i];
    rhs -= jacobians[i].transpose() * bp->offsets_px[i];
  }
  // Views too alike to fix a height (their rays nearly parallel): leave the
  // solver's answer rather than amplify noise along the rays.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(normal);
  if (!(eigen.eigenvalues()(0) > kGaugeMinConditioning * eigen.eigenvalues()(2))) return 0.0;
  const Eigen::Vector3d v = normal.ldlt().solve(rhs);
  for (Eigen::Vector3d& p : bp->points) p -= v;
  for (std::size_t i = 0; i < bp->offsets_px.size(); ++i)
    if (bp->image_used[i]) bp->offsets_px[i] += jacobians[i] * v;
  return v.norm();
}

}  // namespace skyfall
