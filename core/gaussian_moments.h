// Several Gaussians of a cloud as one: their weighted moments (centre,
// covariance including the centres' spread, colour) and the Gaussian with
// those moments. The LOD's merge (weights: mass) and the training's merge
// of coincident Gaussians (weights: opacity) share it.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <vector>

#include "core/gaussians.h"

namespace skyfall {

// Gaussian i's covariance [m^2], in double.
Eigen::Matrix3d GaussianCovariance(const GaussianCloud& cloud, std::size_t i);

struct GaussianMoments {
  double weight = 0;                     // the sum of the members' weights
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();          // weighted mean centre [m]
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();    // sum w (Sigma + d d^T) / weight [m^2]
  std::array<double, 3 * kShCoeffsPerChannel> sh{};        // weighted mean colour
};

// `weight(i)`: each member's weight, > 0.
template <typename WeightFn>
GaussianMoments WeightedMoments(const GaussianCloud& cloud, const std::vector<std::size_t>& members, WeightFn weight) {
  GaussianMoments m;
  for (std::size_t i : members) {
    const double w = weight(i);
    m.weight += w;
    m.mean += w * cloud.means[i].cast<double>();
    for (std::size_t k = 0; k < m.sh.size(); ++k) m.sh[k] += w * cloud.sh[i][k];
  }
  m.mean /= m.weight;
  for (double& c : m.sh) c /= m.weight;
  for (std::size_t i : members) {
    const Eigen::Vector3d d = cloud.means[i].cast<double>() - m.mean;
    m.covariance += weight(i) * (GaussianCovariance(cloud, i) + d * d.transpose());
  }
  m.covariance /= m.weight;
  return m;
}

// The axes and standard deviations of a covariance: a rotation (not a
// reflection) and sigma >= min_sigma_m.
void CovarianceAxes(const Eigen::Matrix3d& covariance, double min_sigma_m, Eigen::Quaterniond* rotation,
                    Eigen::Vector3d* sigma_m);

// Appends the Gaussian of m's centre and colour with `rotation`, `sigma_m`
// and `opacity` (in (0, 1)).
void AppendGaussian(const GaussianMoments& m, const Eigen::Quaterniond& rotation, const Eigen::Vector3d& sigma_m,
                    double opacity, GaussianCloud* out);

}  // namespace skyfall
