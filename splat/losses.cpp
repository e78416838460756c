#include "splat/losses.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/error.h"

namespace skyfall {
namespace {

constexpr int kWindow = 11;
constexpr double kSigma = 1.5;
constexpr double kC1 = 0.01 * 0.01, kC2 = 0.03 * 0.03;

std::array<double, kWindow> GaussianWindow() {
  std::array<double, kWindow> w{};
  double sum = 0;
  for (int i = 0; i < kWindow; ++i) {
    const double d = i - kWindow / 2;
    w[i] = std::exp(-d * d / (2 * kSigma * kSigma));
    sum += w[i];
  }
  for (double& v : w) v /= sum;
  return w;
}

// Separable 'same' convolution with the (symmetric) window, zero padding.
// Symmetric and zero-padded, so it is its own adjoint. Rows run in
// parallel; the inner loops have no bounds tests (edges are done apart), so
// the compiler vectorizes them. In T: float for training (as 3DGS does; the
// SSIM constants C1, C2 keep the variances' rounding harmless), double for
// the finite-difference tests.
template <typename T>
std::vector<T> Blur(const std::vector<T>& in, int w, int h) {
  static const auto win64 = GaussianWindow();
  std::array<T, kWindow> win;
  for (int k = 0; k < kWindow; ++k) win[k] = T(win64[k]);
  constexpr int r = kWindow / 2;
  std::vector<T> tmp(in.size()), out(in.size(), T(0));
  tbb::parallel_for(tbb::blocked_range<int>(0, h, 16), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const T* src = in.data() + static_cast<std::size_t>(y) * w;
      T* dst = tmp.data() + static_cast<std::size_t>(y) * w;
      auto edge = [&](int x) {
        T acc = 0;
        for (int k = -r; k <= r; ++k)
          if (x + k >= 0 && x + k < w) acc += win[k + r] * src[x + k];
        dst[x] = acc;
      };
      for (int x = 0; x < std::min(r, w); ++x) edge(x);
      for (int x = r; x < w - r; ++x) {
        T acc = 0;
        for (int k = 0; k < kWindow; ++k) acc += win[k] * src[x - r + k];
        dst[x] = acc;
      }
      for (int x = std::max(r, w - r); x < w; ++x) edge(x);
    }
  });
  tbb::parallel_for(tbb::blocked_range<int>(0, h, 16), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      T* dst = out.data() + static_cast<std::size_t>(y) * w;
      for (int k = -r; k <= r; ++k) {
        if (y + k < 0 || y + k >= h) continue;
        const T* src = tmp.data() + static_cast<std::size_t>(y + k) * w;
        const T wk = win[k + r];
        for (int x = 0; x < w; ++x) dst[x] += wk * src[x];
      }
    }
  });
  return out;
}

void RequireSameSize(size_t a, size_t b, const char* what) {
  if (a != b) throw Error("loss", what, "sizes differ (" + std::to_string(a) + " vs " + std::to_string(b) + ")");
}

// Stable log(1 + exp(x)).
double Softplus(double x) { return x > 0 ? x + std::log1p(std::exp(-x)) : std::log1p(std::exp(x)); }

}  // namespace

template <typename T>
double L1Loss(const std::vector<T>& x, const std::vector<T>& target, std::vector<T>* grad) {
  RequireSameSize(x.size(), target.size(), "l1");
  double sum = 0;
  const double inv_n = 1.0 / std::max<size_t>(1, x.size());
  if (grad) grad->assign(x.size(), T(0));
  for (size_t k = 0; k < x.size(); ++k) {
    const double d = static_cast<double>(x[k]) - target[k];
    sum += std::abs(d);
    if (grad) (*grad)[k] = T(d > 0 ? inv_n : (d < 0 ? -inv_n : 0.0));
  }
  return sum * inv_n;
}

template <typename T>
double Ssim(const std::vector<T>& x, const std::vector<T>& target, int w, int h, int channels,
            std::vector<T>* grad) {
  RequireSameSize(x.size(), target.size(), "ssim");
  RequireSameSize(x.size(), static_cast<size_t>(w) * h * channels, "ssim image");
  const size_t n = static_cast<size_t>(w) * h;
  if (grad) grad->assign(x.size(), T(0));
  double total = 0;
  const T inv = T(1.0 / static_cast<double>(n * channels));
  const T c1 = T(kC1), c2 = T(kC2);
  for (int c = 0; c < channels; ++c) {
    std::vector<T> a(n), b(n), aa(n), bb(n), ab(n);
    for (size_t p = 0; p < n; ++p) {
      a[p] = x[p * channels + c];
      b[p] = target[p * channels + c];
      aa[p] = a[p] * a[p];
      bb[p] = b[p] * b[p];
      ab[p] = a[p] * b[p];
    }
    const auto mu_a = Blur(a, w, h), mu_b = Blur(b, w, h);
    const auto e_aa = Blur(aa, w, h), e_bb = Blur(bb, w, h), e_ab = Blur(ab, w, h);
    std::vector<T> g_mu(n), dvar(n), dcov(n);
    double channel_total = 0;  // summed in double, in pixel order: deterministic
    for (size_t p = 0; p < n; ++p) {
      const T va = e_aa[p] - mu_a[p] * mu_a[p], vb = e_bb[p] - mu_b[p] * mu_b[p];
      const T cov = e_ab[p] - mu_a[p] * mu_b[p];
      const T l_num = 2 * mu_a[p] * mu_b[p] + c1, l_den = mu_a[p] * mu_a[p] + mu_b[p] * mu_b[p] + c1;
      const T c_num = 2 * cov + c2, c_den = va + vb + c2;
      const T s = (l_num * c_num) / (l_den * c_den);
      channel_total += s;
      // dS/dmu_a, dS/dvar_a, dS/dcov (var and cov as independent statistics),
      // then var_a = E[a^2] - mu_a^2, cov = E[ab] - mu_a mu_b chained to mu_a.
      const T dmu = inv * s * (2 * mu_b[p] / l_num - 2 * mu_a[p] / l_den);
      dvar[p] = inv * (-s / c_den);
      dcov[p] = inv * (2 * s / c_num);
      g_mu[p] = dmu - 2 * mu_a[p] * dvar[p] - mu_b[p] * dcov[p];
    }
    total += channel_total;
    if (!grad) continue;
    // Through the (self-adjoint) blur.
    const auto bg_mu = Blur(g_mu, w, h), bg_var = Blur(dvar, w, h), bg_cov = Blur(dcov, w, h);
    for (size_t p = 0; p < n; ++p) (*grad)[p * channels + c] = bg_mu[p] + 2 * a[p] * bg_var[p] + b[p] * bg_cov[p];
  }
  return total * (1.0 / static_cast<double>(n * channels));
}

template <typename T>
double PhotometricLoss(const std::vector<T>& x, const std::vector<T>& target, int w, int h,
                       const PhotometricLossOptions& o, std::vector<T>* grad) {
  std::vector<T> g_l1, g_ssim;
  const double l1 = L1Loss(x, target, grad ? &g_l1 : nullptr);
  const double ssim = Ssim(x, target, w, h, 3, grad ? &g_ssim : nullptr);
  if (grad) {
    grad->resize(x.size());
    for (size_t k = 0; k < x.size(); ++k) (*grad)[k] = T((1 - o.lambda_dssim) * g_l1[k] - o.lambda_dssim * g_ssim[k]);
  }
  return (1 - o.lambda_dssim) * l1 + o.lambda_dssim * (1 - ssim);
}

template <typename T>
double OpacityEntropy(const std::vector<T>& logits, std::vector<T>* grad) {
  double sum = 0;
  const double inv_n = 1.0 / std::max<size_t>(1, logits.size());
  if (grad) grad->assign(logits.size(), T(0));
  for (size_t k = 0; k < logits.size(); ++k) {
    const double l = logits[k];
    const double a = 1.0 / (1.0 + std::exp(-l));
    // -log a = softplus(-l), -log(1-a) = softplus(l): no log(0) anywhere.
    sum += a * Softplus(-l) + (1 - a) * Softplus(l);
    // dE/dl = log((1-a)/a) * a(1-a) = -l * a(1-a)
    if (grad) (*grad)[k] = T(-l * a * (1 - a) * inv_n);
  }
  return sum * inv_n;
}

template <typename T>
double PearsonDepthLoss(const std::vector<T>& depth, const std::vector<T>& prior,
                        const std::vector<unsigned char>& valid, std::vector<T>* grad) {
  RequireSameSize(depth.size(), prior.size(), "pearson");
  RequireSameSize(depth.size(), valid.size(), "pearson mask");
  if (grad) grad->assign(depth.size(), T(0));
  double n = 0, ma = 0, mb = 0;
  for (size_t k = 0; k < depth.size(); ++k)
    if (valid[k]) {
      ma += depth[k];
      mb += prior[k];
      n += 1;
    }
  if (n < 2) return 0.0;
  ma /= n;
  mb /= n;
  double saa = 0, sbb = 0, sab = 0;
  for (size_t k = 0; k < depth.size(); ++k)
    if (valid[k]) {
      const double a = depth[k] - ma, b = prior[k] - mb;
      saa += a * a;
      sbb += b * b;
      sab += a * b;
    }
  // Zero variance (a flat render or a flat prior): no correlation to learn.
  constexpr double kMinVariance = 1e-12;
  if (saa / n < kMinVariance || sbb / n < kMinVariance) return 0.0;
  const double na = std::sqrt(saa), nb = std::sqrt(sbb);
  const double r = sab / (na * nb);
  // The paper's 1 - |r|: a prior that gives inverse depth (disparity) is
  // as good as one that gives depth.
  const double sign = r >= 0 ? 1.0 : -1.0;
  if (grad) {
    for (size_t k = 0; k < depth.size(); ++k)
      if (valid[k]) {
        const double a = depth[k] - ma, b = prior[k] - mb;
        // d(1 - |r|)/da; the centred expression already sums to zero.
        (*grad)[k] = T(-sign * (b / (na * nb) - r * a / saa));
      }
  }
  return 1.0 - std::abs(r);
}

template <typename T>
double Psnr(const std::vector<T>& x, const std::vector<T>& target) {
  RequireSameSize(x.size(), target.size(), "psnr");
  double mse = 0;
  for (size_t k = 0; k < x.size(); ++k) mse += (static_cast<double>(x[k]) - target[k]) * (static_cast<double>(x[k]) - target[k]);
  mse /= std::max<size_t>(1, x.size());
  return mse > 0 ? -10.0 * std::log10(mse) : 100.0;  // identical images: capped at 100 dB
}

template <typename T>
double SurfaceAnchorLoss(const std::vector<T>& depth, const std::vector<T>& alpha, const std::vector<T>& target,
                         const std::vector<unsigned char>& valid, const SurfaceAnchorOptions& o,
                         std::vector<T>* d_depth, std::vector<T>* d_alpha, const std::vector<float>* depth_weight) {
  RequireSameSize(depth.size(), alpha.size(), "surface anchor (depth, alpha)");
  RequireSameSize(target.size(), alpha.size(), "surface anchor (target, alpha)");
  RequireSameSize(valid.size(), alpha.size(), "surface anchor (valid, alpha)");
  if (depth_weight) RequireSameSize(depth_weight->size(), alpha.size(), "surface anchor (depth weight, alpha)");
  d_depth->assign(alpha.size(), T(0));
  d_alpha->assign(alpha.size(), T(0));
  std::size_t n = 0;
  for (unsigned char v : valid) n += v != 0;
  if (n == 0) return 0.0;
  const double inv_n = 1.0 / static_cast<double>(n), delta = o.huber_delta;
  double loss = 0;
  for (std::size_t p = 0; p < alpha.size(); ++p) {
    if (!valid[p]) continue;
    loss += o.lambda_alpha * (1.0 - alpha[p]) * inv_n;
    (*d_alpha)[p] = static_cast<T>(-o.lambda_alpha * inv_n);
    if (alpha[p] < o.min_alpha) continue;
    const double e = static_cast<double>(depth[p]) - target[p];
    const double a = std::abs(e);
    const double w = o.lambda_depth * (depth_weight ? (*depth_weight)[p] : 1.0f) * inv_n;
    loss += w * (a <= delta ? 0.5 * e * e : delta * (a - 0.5 * delta));
    (*d_depth)[p] = static_cast<T>(w * (a <= delta ? e : delta * (e > 0 ? 1.0 : -1.0)));
  }
  return loss;
}

#define SKYFALL_INSTANTIATE_LOSSES(T)                                                                       \
  template double L1Loss(const std::vector<T>&, const std::vector<T>&, std::vector<T>*);                   \
  template double Ssim(const std::vector<T>&, const std::vector<T>&, int, int, int, std::vector<T>*);      \
  template double PhotometricLoss(const std::vector<T>&, const std::vector<T>&, int, int,                  \
                                  const PhotometricLossOptions&, std::vector<T>*);                        \
  template double OpacityEntropy(const std::vector<T>&, std::vector<T>*);                                   \
  template double PearsonDepthLoss(const std::vector<T>&, const std::vector<T>&,                           \
                                   const std::vector<unsigned char>&, std::vector<T>*);                     \
  template double Psnr(const std::vector<T>&, const std::vector<T>&);                                       \
  template double SurfaceAnchorLoss(const std::vector<T>&, const std::vector<T>&, const std::vector<T>&,      \
                                    const std::vector<unsigned char>&, const SurfaceAnchorOptions&,         \
                                    std::vector<T>*, std::vector<T>*, const std::vector<float>*);
SKYFALL_INSTANTIATE_LOSSES(float)
SKYFALL_INSTANTIATE_LOSSES(double)

}  // namespace skyfall
