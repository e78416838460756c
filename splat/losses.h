// Training losses with their gradients. Images are planar-interleaved
// float/double RGB (3 values per pixel, row-major), as the rasterizer outputs.
#pragma once

#include <cstdint>
#include <vector>

namespace skyfall {

// Mean absolute error over all values; `grad` (same size) receives dL/dx.
template <typename T>
double L1Loss(const std::vector<T>& x, const std::vector<T>& target, std::vector<T>* grad);

// Mean SSIM over pixels and channels (11x11 Gaussian window, sigma 1.5,
// C1 = 0.01^2, C2 = 0.03^2, zero padding as in the 3DGS reference), and its
// gradient with respect to `x`.
template <typename T>
double Ssim(const std::vector<T>& x, const std::vector<T>& target, int width, int height, int channels,
            std::vector<T>* grad);

// The mean of Ssim(x, target) over `targets` (at least one), and its
// gradient: the render's own statistics are blurred once for all targets.
template <typename T>
double SsimMean(const std::vector<T>& x, const std::vector<const std::vector<T>*>& targets, int width, int height,
                int channels, std::vector<T>* grad);

// One pixel's SSIM from its windowed statistics (means, variances and
// covariance of render a and target b), and its partial derivatives with the
// variance and covariance taken as independent statistics (SsimMean chains
// them to the pixels). The derivatives are written without dividing by the
// numerators 2 mu_a mu_b + c1 and 2 cov + c2: either is exactly 0 in float
// where render and target are anti-correlated just so, and ssim / numerator
// would be 0 / 0 there.
template <typename T>
struct SsimTerms {
  T ssim, d_mu_a, d_var_a, d_cov;
};
template <typename T>
inline SsimTerms<T> SsimAtPixel(T mu_a, T mu_b, T var_a, T var_b, T cov, T c1, T c2) {
  const T l_num = 2 * mu_a * mu_b + c1, l_den = mu_a * mu_a + mu_b * mu_b + c1;
  const T c_num = 2 * cov + c2, c_den = var_a + var_b + c2;
  const T den = l_den * c_den;
  const T ssim = (l_num * c_num) / den;
  return {ssim, 2 * mu_b * c_num / den - ssim * 2 * mu_a / l_den, -ssim / c_den, 2 * l_num / den};
}

// The reconstruction loss of 3DGS / Skyfall-GS: (1 - lambda) L1 + lambda (1 - SSIM).
struct PhotometricLossOptions {
  double lambda_dssim = 0.2;
};
template <typename T>
double PhotometricLoss(const std::vector<T>& x, const std::vector<T>& target, int width, int height,
                       const PhotometricLossOptions& options, std::vector<T>* grad);
// Its mean over several targets (at least one; e.g. the N_s refined samples
// of one view), computed at the cost of little more than one.
template <typename T>
double PhotometricLossMean(const std::vector<T>& x, const std::vector<const std::vector<T>*>& targets, int width,
                           int height, const PhotometricLossOptions& options, std::vector<T>* grad);

// Opacity entropy -a log a - (1 - a) log(1 - a) with a = sigmoid(logit),
// averaged over Gaussians. Written in the logit, so it is finite and smooth
// for any logit (a = 0 or 1 exactly is a limit, with value and gradient 0).
// `grad` receives dL/dlogit.
template <typename T>
double OpacityEntropy(const std::vector<T>& logits, std::vector<T>* grad);

// 1 - |Pearson correlation| between rendered and prior depth (Skyfall-GS
// eq. for L_depth) over the pixels where `valid` is non-zero. When either depth has (numerically) zero
// variance the correlation is undefined: the loss is 0 with zero gradient.
template <typename T>
double PearsonDepthLoss(const std::vector<T>& depth, const std::vector<T>& prior,
                        const std::vector<unsigned char>& valid, std::vector<T>* grad);

// Anchoring a render to a known surface, averaged over the pixels where
// `valid` is non-zero: lambda_depth * Huber_delta(depth - target) (quadratic
// within delta, linear beyond, so the surface's own errors at edges pull
// with bounded force) + lambda_alpha * (1 - alpha). The depth term counts only
// where alpha >= min_alpha (below it the expected depth is undefined); the
// opacity term everywhere the surface is seen. `depth` and `target` share one
// reference. `depth_weight` (optional, per pixel in [0, 1]) scales the depth
// term by the target's confidence. `d_depth` and `d_alpha` receive the
// gradients (sized like alpha).
struct SurfaceAnchorOptions {
  double lambda_depth = 0.0;
  double lambda_alpha = 0.0;
  double huber_delta = 1.0;  // [depth units]
  double min_alpha = 0.1;
};
template <typename T>
double SurfaceAnchorLoss(const std::vector<T>& depth, const std::vector<T>& alpha, const std::vector<T>& target,
                         const std::vector<unsigned char>& valid, const SurfaceAnchorOptions& options,
                         std::vector<T>* d_depth, std::vector<T>* d_alpha,
                         const std::vector<float>* depth_weight = nullptr);

// Gaussians on the surface stay on it: for each Gaussian whose centre lies
// within band_m of the surface height below it (`surface_height_m[i]`, NaN:
// none), lambda * weight_i * 0.5 * (z_i - height_i)^2, averaged over all
// Gaussians. Centres further off (walls, the metres a wrong surface is off at
// an edge) are left to the other losses. The photometric loss hardly sees a
// centre's height on near-nadir views, so without this the centres of a flat
// roof scatter by a decimetre and the nadir median depth (the DSM) with them.
// `weight` (optional, per Gaussian in [0, 1]): the surface's confidence.
// Adds the gradient to `d_z` (one per Gaussian).
struct SurfaceHeightOptions {
  double lambda = 0.0;  // per m^2
  double band_m = 1.0;
};
double SurfaceHeightLoss(const std::vector<float>& z_m, const std::vector<float>& surface_height_m,
                         const SurfaceHeightOptions& options, std::vector<float>* d_z,
                         const std::vector<float>* weight = nullptr);

// Peak signal-to-noise ratio of images in [0, 1] [dB].
template <typename T>
double Psnr(const std::vector<T>& x, const std::vector<T>& target);

// The same over the pixels where `valid` (1 per pixel of 3 channels; empty:
// every pixel) is non-zero: a view's pixels without data (nodata, zero fill,
// a crop beyond the image) are not scored. NaN when no pixel is valid.
double MaskedPsnr(const std::vector<float>& rgb, const std::vector<float>& target,
                  const std::vector<std::uint8_t>& valid);

// Least-squares line b = gain * a + offset through pairs (a, b): one colour
// channel of an image mapped onto another's.
struct LineFit {
  double n = 0, sum_a = 0, sum_b = 0, sum_aa = 0, sum_ab = 0;
  void Add(double a, double b) {
    ++n;
    sum_a += a;
    sum_b += b;
    sum_aa += a * a;
    sum_ab += a * b;
  }
  double VarianceA() const { return sum_aa / n - (sum_a / n) * (sum_a / n); }
  double Gain() const { return (sum_ab / n - (sum_a / n) * (sum_b / n)) / VarianceA(); }
  double Offset(double gain) const { return sum_b / n - gain * sum_a / n; }
};

// PSNR [dB] of the right half of an RGB `render` against `target` (3 floats
// per pixel in [0, 1], row-major) after each channel of the render is mapped
// by the gain and offset that best fit (least squares) the left half. A
// held-out satellite image was taken on a date the model never saw; its
// radiometry is fitted on pixels the score does not use (NeRF-W's
// half-image protocol, with a colour affine in place of an embedding).
// `valid` (empty: all) masks pixels without data out of both halves. NaN
// when either half has no valid pixel.
double HalfFittedPsnr(const std::vector<float>& render, const std::vector<float>& target, int width_px,
                      int height_px, const std::vector<std::uint8_t>& valid = {});

}  // namespace skyfall
