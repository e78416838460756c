#include "sfm/rpc_to_pinhole.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "core/error.h"

namespace skyfall {
namespace {

struct Correspondence {
  Eigen::Vector3d world;  // ENU [m]
  Eigen::Vector2d pixel;  // RPC image coordinates [px]
};

// Samples the RPC on a grid of pixels x heights and localizes each sample, so
// the grid covers exactly the image. `cell_centres` places samples at the
// centres of a finer grid (the check grid never reuses fit samples).
std::vector<Correspondence> SampleRpc(const RpcModel& rpc, int width, int height, double h0, double h1,
                                      int nc, int nr, int nh, bool cell_centres,
                                      const std::function<Eigen::Vector3d(const GeodeticPoint&)>& enu) {
  auto at = [&](double lo, double hi, int i, int n) {
    return cell_centres ? lo + (hi - lo) * (i + 0.5) / n : lo + (hi - lo) * i / (n - 1);
  };
  std::vector<Correspondence> out;
  out.reserve(static_cast<size_t>(nc) * nr * nh);
  for (int k = 0; k < nh; ++k)
    for (int j = 0; j < nr; ++j)
      for (int i = 0; i < nc; ++i) {
        const double col = at(0.0, width - 1.0, i, nc), row = at(0.0, height - 1.0, j, nr);
        const double h = at(h0, h1, k, nh);
        const Eigen::Vector2d ll = Localize(rpc, col, row, h);
        out.push_back({enu({ll.x(), ll.y(), h}), {col, row}});
      }
  return out;
}

// Similarity that moves points to zero mean and mean distance sqrt(dim)
// (Hartley); identity when normalization is off.
template <int Dim>
Eigen::Matrix<double, Dim + 1, Dim + 1> Normalizer(const std::vector<Eigen::Matrix<double, Dim, 1>>& pts,
                                                    bool enabled) {
  Eigen::Matrix<double, Dim + 1, Dim + 1> T = Eigen::Matrix<double, Dim + 1, Dim + 1>::Identity();
  if (!enabled) return T;
  Eigen::Matrix<double, Dim, 1> mean = Eigen::Matrix<double, Dim, 1>::Zero();
  for (const auto& p : pts) mean += p;
  mean /= static_cast<double>(pts.size());
  double dist = 0;
  for (const auto& p : pts) dist += (p - mean).norm();
  dist /= static_cast<double>(pts.size());
  const double s = std::sqrt(static_cast<double>(Dim)) / dist;
  T.template topLeftCorner<Dim, Dim>() *= s;
  T.template topRightCorner<Dim, 1>() = -s * mean;
  return T;
}

Eigen::Matrix<double, 3, 4> Dlt(const std::vector<Correspondence>& corr, bool normalize) {
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
  for (const auto& c : corr) {
    X.push_back(c.world);
    x.push_back(c.pixel);
  }
  const Eigen::Matrix4d T3 = Normalizer<3>(X, normalize);
  const Eigen::Matrix3d T2 = Normalizer<2>(x, normalize);
  Eigen::MatrixXd A(2 * corr.size(), 12);
  for (size_t n = 0; n < corr.size(); ++n) {
    const Eigen::Vector4d Xh = T3 * X[n].homogeneous();
    const Eigen::Vector3d xh = T2 * x[n].homogeneous();
    A.row(2 * n) << Xh.transpose(), Eigen::RowVector4d::Zero(), -xh.x() * Xh.transpose();
    A.row(2 * n + 1) << Eigen::RowVector4d::Zero(), Xh.transpose(), -xh.y() * Xh.transpose();
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeThinV);
  const Eigen::VectorXd p = svd.matrixV().col(11);
  Eigen::Matrix<double, 3, 4> Pn;
  Pn << p.segment<4>(0).transpose(), p.segment<4>(4).transpose(), p.segment<4>(8).transpose();
  return T2.inverse() * Pn * T3;
}

// P = K [R | t] with K upper triangular, positive diagonal, K(2,2) = 1.
PinholeCamera Decompose(Eigen::Matrix<double, 3, 4> P, int width, int height) {
  if (P.leftCols<3>().determinant() < 0) P = -P;
  // RQ decomposition through QR of the row-reversed, transposed matrix.
  Eigen::Matrix3d flip;
  flip << 0, 0, 1, 0, 1, 0, 1, 0, 0;
  const Eigen::Matrix3d M = P.leftCols<3>();
  const Eigen::HouseholderQR<Eigen::Matrix3d> qr((flip * M).transpose());
  const Eigen::Matrix3d Q = qr.householderQ();
  const Eigen::Matrix3d Rt = qr.matrixQR().triangularView<Eigen::Upper>();
  Eigen::Matrix3d K = flip * Rt.transpose() * flip;
  Eigen::Matrix3d R = flip * Q.transpose();
  const Eigen::Vector3d signs(K(0, 0) < 0 ? -1 : 1, K(1, 1) < 0 ? -1 : 1, K(2, 2) < 0 ? -1 : 1);
  K = K * signs.asDiagonal();
  R = signs.asDiagonal() * R;
  const Eigen::Vector3d t = K.inverse() * P.col(3);
  K /= K(2, 2);
  PinholeCamera cam;
  cam.fx = K(0, 0);
  cam.fy = K(1, 1);
  cam.skew = K(0, 1);
  cam.cx = K(0, 2);
  cam.cy = K(1, 2);
  cam.cam_from_world_rotation = R;
  cam.cam_from_world_translation = t;
  cam.width_px = width;
  cam.height_px = height;
  return cam;
}

struct ReprojectionCost {
  Eigen::Vector3d world;
  Eigen::Vector2d pixel;
  Eigen::Matrix3d rotation0;  // the DLT rotation; the solver refines a small delta
  template <typename T>
  bool operator()(const T* intrinsics, const T* delta_angle_axis, const T* centre, T* residual) const {
    // x_cam = R(delta) * R0 * (X - C): X - C is formed first, in double
    // precision, from two ~1e5 m quantities.
    T d[3] = {T(world.x()) - centre[0], T(world.y()) - centre[1], T(world.z()) - centre[2]};
    T v[3];
    for (int r = 0; r < 3; ++r) v[r] = T(rotation0(r, 0)) * d[0] + T(rotation0(r, 1)) * d[1] + T(rotation0(r, 2)) * d[2];
    T c[3];
    ceres::AngleAxisRotatePoint(delta_angle_axis, v, c);
    const T xn = c[0] / c[2], yn = c[1] / c[2];
    residual[0] = intrinsics[0] * xn + intrinsics[2] * yn + intrinsics[3] - T(pixel.x());
    residual[1] = intrinsics[1] * yn + intrinsics[4] - T(pixel.y());
    return true;
  }
};

PinholeCamera Refine(const PinholeCamera& start, const std::vector<Correspondence>& corr, bool skew) {
  double intrinsics[5] = {start.fx, start.fy, skew ? start.skew : 0.0, start.cx, start.cy};
  double delta[3] = {0, 0, 0};
  Eigen::Vector3d centre = start.Centre();
  ceres::Problem problem;
  for (const auto& c : corr) {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 5, 3, 3>(
            new ReprojectionCost{c.world, c.pixel, start.cam_from_world_rotation}),
        nullptr, intrinsics, delta, centre.data());
  }
  if (!skew) problem.SetManifold(intrinsics, new ceres::SubsetManifold(5, {2}));
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 200;
  options.function_tolerance = 1e-16;
  options.gradient_tolerance = 1e-16;
  options.parameter_tolerance = 1e-16;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  PinholeCamera cam = start;
  cam.fx = intrinsics[0];
  cam.fy = intrinsics[1];
  cam.skew = intrinsics[2];
  cam.cx = intrinsics[3];
  cam.cy = intrinsics[4];
  Eigen::Matrix3d dR;
  ceres::AngleAxisToRotationMatrix(delta, ceres::ColumnMajorAdapter3x3(dR.data()));
  cam.cam_from_world_rotation = dR * start.cam_from_world_rotation;
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * centre;
  return cam;
}

void Errors(const PinholeCamera& cam, const std::vector<Correspondence>& corr, double* max_px, double* mean_px) {
  double worst = 0, sum = 0;
  for (const auto& c : corr) {
    const double e = (cam.Project(c.world) - c.pixel).norm();
    worst = std::max(worst, e);
    sum += e;
  }
  *max_px = worst;
  *mean_px = sum / static_cast<double>(corr.size());
}

}  // namespace

void PinholeFitOptions::Check() const { CheckOptionRanges(*this, "pinhole"); }

PinholeFit ApproximateRpcByPinhole(
    const RpcModel& rpc, int width_px, int height_px, EllipsoidHeightM min_height, EllipsoidHeightM max_height,
    const std::function<Eigen::Vector3d(const GeodeticPoint&)>& enu_from_geodetic,
    const PinholeFitOptions& options) {
  options.Check();
  const double min_height_m = min_height.value, max_height_m = max_height.value;
  if (width_px < 2 || height_px < 2) throw Error("pinhole", "image", "is smaller than 2x2 px");
  if (!(min_height_m < max_height_m)) {
    throw Error("pinhole", "height range", "is empty: a pinhole needs 3D extent to be determined");
  }
  const auto fit = SampleRpc(rpc, width_px, height_px, min_height_m, max_height_m, options.grid_cols,
                             options.grid_rows, options.grid_heights, false, enu_from_geodetic);
  const auto check = SampleRpc(rpc, width_px, height_px, min_height_m, max_height_m, options.check_cols,
                               options.check_rows, options.check_heights, true, enu_from_geodetic);
  PinholeFit out;
  out.camera = Decompose(Dlt(fit, options.hartley_normalization), width_px, height_px);
  Errors(out.camera, check, &out.dlt_max_error_px, &out.dlt_mean_error_px);
  if (out.camera.Depth(fit.front().world) <= 0) {
    throw Error("pinhole", "dlt", "the decomposed camera looks away from the scene");
  }
  if (options.refine) out.camera = Refine(out.camera, fit, options.estimate_skew);
  Errors(out.camera, check, &out.max_error_px, &out.mean_error_px);
  return out;
}

}  // namespace skyfall
