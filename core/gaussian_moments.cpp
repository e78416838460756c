#include "core/gaussian_moments.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>

namespace skyfall {

Eigen::Matrix3d GaussianCovariance(const GaussianCloud& cloud, std::size_t i) {
  const Eigen::Vector4f& q = cloud.rotations[i];
  const Eigen::Matrix3d r = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  const Eigen::Vector3d s = cloud.log_scales[i].cast<double>().array().exp();
  return r * s.array().square().matrix().asDiagonal() * r.transpose();
}

void CovarianceAxes(const Eigen::Matrix3d& covariance, double min_sigma_m, Eigen::Quaterniond* rotation,
                    Eigen::Vector3d* sigma_m) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(covariance);
  Eigen::Matrix3d axes = eig.eigenvectors();
  if (axes.determinant() < 0) axes.col(0) = -axes.col(0);  // a rotation, not a reflection
  *sigma_m = eig.eigenvalues().cwiseMax(min_sigma_m * min_sigma_m).cwiseSqrt();
  *rotation = Eigen::Quaterniond(axes);
}

void AppendGaussian(const GaussianMoments& m, const Eigen::Quaterniond& q, const Eigen::Vector3d& sigma_m,
                    double opacity, GaussianCloud* out) {
  out->means.push_back(m.mean.cast<float>());
  out->log_scales.push_back(sigma_m.array().log().matrix().cast<float>());
  out->rotations.push_back(Eigen::Vector4f(q.w(), q.x(), q.y(), q.z()));
  out->opacity_logits.push_back(static_cast<float>(std::log(opacity / (1.0 - opacity))));
  std::array<float, 3 * kShCoeffsPerChannel> sh{};
  for (std::size_t k = 0; k < m.sh.size(); ++k) sh[k] = static_cast<float>(m.sh[k]);
  out->sh.push_back(sh);
}

}  // namespace skyfall
