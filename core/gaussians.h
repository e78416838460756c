// A cloud of 3D Gaussians in a local metric frame (the AOI's or tile's ENU
// frame), with the parameters the optimizer works on: log scales, an
// unnormalized rotation quaternion (w, x, y, z), an opacity logit and
// spherical-harmonics colour of degree 0-1.
// Positions are float: within a few km of the frame origin that is better
// than 0.5 mm. Camera transforms are applied in double (cameras are far).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

namespace skyfall {

// Real spherical-harmonics constants (as in the 3DGS reference code).
inline constexpr double kShC0 = 0.28209479177387814;
inline constexpr double kShC1 = 0.4886025119029199;

// Coefficients per channel for SH degree 1: [dc, y, z, x] basis order.
inline constexpr int kShCoeffsPerChannel = 4;

template <typename T>
struct GaussianCloudT {
  std::vector<Eigen::Matrix<T, 3, 1>> means;       // [m]
  std::vector<Eigen::Matrix<T, 3, 1>> log_scales;  // log of the standard deviations [log m]
  std::vector<Eigen::Matrix<T, 4, 1>> rotations;   // quaternion (w, x, y, z), any norm > 0
  std::vector<T> opacity_logits;                   // opacity = sigmoid(logit)
  std::vector<std::array<T, 3 * kShCoeffsPerChannel>> sh;  // [channel * 4 + k]

  std::size_t size() const { return means.size(); }
  void resize(std::size_t n) {
    means.resize(n);
    log_scales.resize(n);
    rotations.resize(n);
    opacity_logits.resize(n);
    sh.resize(n);
  }
  // Appends Gaussian `i` of `other`.
  void Append(const GaussianCloudT& other, std::size_t i) {
    means.push_back(other.means[i]);
    log_scales.push_back(other.log_scales[i]);
    rotations.push_back(other.rotations[i]);
    opacity_logits.push_back(other.opacity_logits[i]);
    sh.push_back(other.sh[i]);
  }
};

using GaussianCloud = GaussianCloudT<float>;

// Colour <-> SH degree-0 coefficient, so that a plain colour c in [0, 1]
// renders as c.
inline double ShDcFromColour(double c) { return (c - 0.5) / kShC0; }

// A Gaussian's opacity from its stored logit (the sigmoid), in double.
inline double OpacityOfLogit(double logit) { return 1.0 / (1.0 + std::exp(-logit)); }

}  // namespace skyfall
