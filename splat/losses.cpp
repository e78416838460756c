#include "splat/losses.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

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

// The SSIM's statistics are blurred with a separable 'same' convolution by
// the (symmetric) window, zero padding: symmetric and zero-padded, so it is
// its own adjoint, and the gradient goes back through the same blur. Both
// passes sum the 11 taps of a pixel in registers, in tap order, with the
// pixels along a row in the vector lanes. In T: float for training (as 3DGS
// does; the SSIM constants C1, C2 keep the variances' rounding harmless),
// double for the finite-difference tests.
template <typename T>
std::array<T, kWindow> Window() {
  static const auto win64 = GaussianWindow();
  std::array<T, kWindow> win;
  for (int k = 0; k < kWindow; ++k) win[k] = T(win64[k]);
  return win;
}

// dst[x] = sum over k of win[k] * row[x + k], in tap order: `row` holds
// w + 2r values, the row with r zeros on either side.
template <typename T>
void HorizontalTaps(const T* row, const std::array<T, kWindow>& win, T* __restrict dst, int w) {
  for (int x = 0; x < w; ++x) {
    T acc = 0;
#pragma GCC unroll 11
    for (int k = 0; k < kWindow; ++k) acc += win[k] * row[x + k];
    dst[x] = acc;
  }
}

// dst[x] = sum over k of win[k] * src[k][x], in tap order. The rows as
// separate restrict pointers: through the array GCC does not vectorize.
template <typename T>
void VerticalTaps(const T* const* src, const std::array<T, kWindow>& win, T* __restrict dst, int w) {
  static_assert(kWindow == 11, "one pointer per tap");
  const T* __restrict s0 = src[0];
  const T* __restrict s1 = src[1];
  const T* __restrict s2 = src[2];
  const T* __restrict s3 = src[3];
  const T* __restrict s4 = src[4];
  const T* __restrict s5 = src[5];
  const T* __restrict s6 = src[6];
  const T* __restrict s7 = src[7];
  const T* __restrict s8 = src[8];
  const T* __restrict s9 = src[9];
  const T* __restrict s10 = src[10];
  for (int x = 0; x < w; ++x) {
    T acc = 0;
    acc += win[0] * s0[x];
    acc += win[1] * s1[x];
    acc += win[2] * s2[x];
    acc += win[3] * s3[x];
    acc += win[4] * s4[x];
    acc += win[5] * s5[x];
    acc += win[6] * s6[x];
    acc += win[7] * s7[x];
    acc += win[8] * s8[x];
    acc += win[9] * s9[x];
    acc += win[10] * s10[x];
    dst[x] = acc;
  }
}

// The last kWindow rows of `planes` planes, horizontally blurred, row y of
// a plane in slot y % kWindow: what the vertical pass of the blur reads.
template <typename T>
class RowRing {
 public:
  RowRing(int planes, int w) : w_(w), data_(static_cast<std::size_t>(planes) * kWindow * w) {}
  T* Row(int plane, int y) { return data_.data() + (static_cast<std::size_t>(plane) * kWindow + y % kWindow) * w_; }
  // The vertical pass at row y of one plane; rows outside [0, h) are zero.
  void Blur(int plane, int y, int h, const std::array<T, kWindow>& win, const T* zeros, T* dst) {
    constexpr int r = kWindow / 2;
    const T* src[kWindow];
    for (int k = 0; k < kWindow; ++k) {
      const int yy = y + k - r;
      src[k] = yy < 0 || yy >= h ? zeros : Row(plane, yy);
    }
    VerticalTaps(src, win, dst, w_);
  }

 private:
  int w_;
  std::vector<T> data_;
};

// SSIM bands are this many rows: a band recomputes 2 r rows of statistics
// and r rows of gradient terms on either side, and 3 channels x 3 bands of a
// 384-row view keep 2 cores busy.
constexpr int kSsimBandRows = 128;

// SSIM's row planes. Statistic planes: a, a^2, then b, b^2, ab of each
// target. Gradient planes: the mu_a and var_a terms summed over targets
// (they are blurred alike), then each target's cov term (its blur is
// multiplied by that target's b).
enum { kA, kAA };
enum { kGMu, kDVar };
constexpr int BPlane(int s, int k) { return 2 + 3 * s + k; }  // target s; k: 0 b, 1 b^2, 2 ab

// One row's SSIM terms from its blurred statistics (the planes above):
// writes each target's cov gradient term and sums the mu_a and var_a terms
// into `g` (zeroed here); returns the row's SSIM summed over the targets.
template <typename T>
double SsimRowTerms(const T* blurred, int S, int w, T inv, T c1, T c2, T* row_ssim, T* g) {
  const T* mu_a = &blurred[kA * w];
  const T* e_aa = &blurred[kAA * w];
  std::fill(g, g + static_cast<std::size_t>(2 + S) * w, T(0));
  double total = 0;
  for (int s = 0; s < S; ++s) {
    const T* mu_b = &blurred[BPlane(s, 0) * w];
    const T* e_bb = &blurred[BPlane(s, 1) * w];
    const T* e_ab = &blurred[BPlane(s, 2) * w];
    for (int p = 0; p < w; ++p) {
      const T va = e_aa[p] - mu_a[p] * mu_a[p], vb = e_bb[p] - mu_b[p] * mu_b[p];
      const T cov = e_ab[p] - mu_a[p] * mu_b[p];
      const SsimTerms<T> t = SsimAtPixel(mu_a[p], mu_b[p], va, vb, cov, c1, c2);
      row_ssim[p] = t.ssim;
      // var_a = E[a^2] - mu_a^2 and cov = E[ab] - mu_a mu_b chained to mu_a.
      const T dvar = inv * t.d_var_a, dcov = inv * t.d_cov;
      const T dmu = inv * t.d_mu_a;
      g[kDVar * w + p] += dvar;
      g[(2 + s) * w + p] = dcov;
      g[kGMu * w + p] += dmu - 2 * mu_a[p] * dvar - mu_b[p] * dcov;
    }
    for (int p = 0; p < w; ++p) total += row_ssim[p];  // summed after the row: the pixel loop vectorizes
  }
  return total;
}

// One channel's SSIM over rows [y0, y1), streamed: each input row's
// statistics (a, a^2, and b, b^2, ab per target) are blurred horizontally
// into a ring of 11 rows, the vertical pass gives a row of blurred
// statistics, whose SSIM terms are blurred back through a second ring into
// the gradient. No statistic or gradient plane goes through memory as a
// whole image: 24 planes of a 512 x 384 view did, and the loss was bound by
// that traffic. Writes the row sums of SSIM into row_total[c * h + y] and,
// with `grad`, channel c of rows [y0, y1) of it.
template <typename T>
void SsimBand(const std::vector<T>& x, const std::vector<const std::vector<T>*>& targets, int w, int h,
              int channels, int c, int y0, int y1, std::vector<double>* row_total, std::vector<T>* grad) {
  constexpr int r = kWindow / 2;
  const int S = static_cast<int>(targets.size());
  const std::size_t n = static_cast<std::size_t>(w) * h;
  const T inv = T(1.0 / static_cast<double>(n * channels * S));
  const T c1 = T(kC1), c2 = T(kC2);
  const std::array<T, kWindow> win = Window<T>();
  const int stats_planes = 2 + 3 * S, grad_planes = 2 + S;
  RowRing<T> stats(stats_planes, w), terms(grad_planes, w);
  std::vector<T> padded(static_cast<std::size_t>(w) + 2 * r, T(0)), zeros(static_cast<std::size_t>(w), T(0));
  std::vector<T> blurred(static_cast<std::size_t>(stats_planes) * w), g(static_cast<std::size_t>(grad_planes) * w);
  std::vector<T> row_ssim(static_cast<std::size_t>(w));
  auto pixel = [&](const std::vector<T>& image, int y, int px) {
    return image[(static_cast<std::size_t>(y) * w + px) * channels + c];
  };
  // Blurs one row of one statistic (or gradient term) horizontally into its ring.
  auto blur_row = [&](RowRing<T>& ring, int plane, int y, auto value) {
    for (int px = 0; px < w; ++px) padded[r + px] = value(px);
    HorizontalTaps(padded.data(), win, ring.Row(plane, y), w);
  };
  auto add_input_row = [&](int y) {
    blur_row(stats, kA, y, [&](int px) { return pixel(x, y, px); });
    blur_row(stats, kAA, y, [&](int px) { const T a = pixel(x, y, px); return a * a; });
    for (int s = 0; s < S; ++s) {
      const std::vector<T>& t = *targets[s];
      blur_row(stats, BPlane(s, 0), y, [&](int px) { return pixel(t, y, px); });
      blur_row(stats, BPlane(s, 1), y, [&](int px) { const T b = pixel(t, y, px); return b * b; });
      blur_row(stats, BPlane(s, 2), y, [&](int px) { return pixel(x, y, px) * pixel(t, y, px); });
    }
  };
  // The gradient at row y of the band, once the terms of rows up to y + r are in their ring.
  std::vector<T> d_blurred(static_cast<std::size_t>(grad_planes) * w);
  auto output_row = [&](int y) {
    for (int k = 0; k < grad_planes; ++k) terms.Blur(k, y, h, win, zeros.data(), &d_blurred[k * w]);
    for (int px = 0; px < w; ++px) {
      T v = d_blurred[kGMu * w + px] + 2 * pixel(x, y, px) * d_blurred[kDVar * w + px];
      for (int s = 0; s < S; ++s) v += pixel(*targets[s], y, px) * d_blurred[(2 + s) * w + px];
      (*grad)[(static_cast<std::size_t>(y) * w + px) * channels + c] = v;
    }
  };
  // Rows whose SSIM terms the band needs: its own, and r more on either
  // side for the gradient's blur.
  const int t0 = grad ? std::max(0, y0 - r) : y0, t1 = grad ? std::min(h, y1 + r) : y1;
  int next_input = std::max(0, t0 - r), next_output = y0;
  for (int y = t0; y < t1; ++y) {
    for (; next_input <= std::min(h - 1, y + r); ++next_input) add_input_row(next_input);
    for (int k = 0; k < stats_planes; ++k) stats.Blur(k, y, h, win, zeros.data(), &blurred[k * w]);
    const double total = SsimRowTerms<T>(blurred.data(), S, w, inv, c1, c2, row_ssim.data(), g.data());
    if (y >= y0 && y < y1) (*row_total)[static_cast<std::size_t>(c) * h + y] = total;
    if (!grad) continue;
    for (int k = 0; k < grad_planes; ++k) blur_row(terms, k, y, [&](int px) { return g[k * w + px]; });
    for (; next_output < y1 && std::min(h - 1, next_output + r) <= y; ++next_output) output_row(next_output);
  }
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
  const double inv_n = 1.0 / std::max<size_t>(1, x.size());
  if (grad) grad->resize(x.size());
  // Chunks in parallel, each summed in double, the chunks' sums added in
  // order: the same result whatever the threads.
  constexpr size_t kChunk = 1 << 14;
  std::vector<double> chunk_sum((x.size() + kChunk - 1) / kChunk, 0.0);
  tbb::parallel_for(size_t{0}, chunk_sum.size(), [&](size_t c) {
    double sum = 0;
    for (size_t k = c * kChunk; k < std::min(x.size(), (c + 1) * kChunk); ++k) {
      const double d = static_cast<double>(x[k]) - target[k];
      sum += std::abs(d);
      if (grad) (*grad)[k] = T(d > 0 ? inv_n : (d < 0 ? -inv_n : 0.0));
    }
    chunk_sum[c] = sum;
  });
  double sum = 0;
  for (double v : chunk_sum) sum += v;
  return sum * inv_n;
}

template <typename T>
double SsimMean(const std::vector<T>& x, const std::vector<const std::vector<T>*>& targets, int w, int h, int channels,
                std::vector<T>* grad) {
  if (targets.empty()) throw Error("loss", "ssim", "no target image");
  for (const auto* t : targets) RequireSameSize(x.size(), t->size(), "ssim");
  RequireSameSize(x.size(), static_cast<size_t>(w) * h * channels, "ssim image");
  const size_t n = static_cast<size_t>(w) * h;
  if (grad) grad->resize(x.size());  // every value is written by its channel's band
  // Channels and bands of rows in parallel; each row's sum in double, the
  // rows summed in order (deterministic whatever the scheduling).
  const int bands = std::max(1, (h + kSsimBandRows - 1) / kSsimBandRows);
  std::vector<double> row_total(static_cast<size_t>(h) * channels, 0.0);
  tbb::parallel_for(0, channels * bands, [&](int task) {
    const int c = task / bands, band = task % bands;
    const int y0 = static_cast<int>(static_cast<long>(h) * band / bands);
    const int y1 = static_cast<int>(static_cast<long>(h) * (band + 1) / bands);
    SsimBand(x, targets, w, h, channels, c, y0, y1, &row_total, grad);
  });
  double total = 0;
  for (double t : row_total) total += t;
  return total * (1.0 / static_cast<double>(n * channels * targets.size()));
}

template <typename T>
double Ssim(const std::vector<T>& x, const std::vector<T>& target, int w, int h, int channels,
            std::vector<T>* grad) {
  return SsimMean(x, {&target}, w, h, channels, grad);
}

template <typename T>
double PhotometricLossMean(const std::vector<T>& x, const std::vector<const std::vector<T>*>& targets, int w, int h,
                           const PhotometricLossOptions& o, std::vector<T>* grad) {
  if (targets.empty()) throw Error("loss", "photometric", "no target image");
  std::vector<T> g_l1, g_ssim;
  double l1 = L1Loss(x, *targets[0], grad ? &g_l1 : nullptr);
  for (size_t s = 1; s < targets.size(); ++s) {
    l1 += L1Loss(x, *targets[s], grad ? &g_ssim : nullptr);  // g_ssim as scratch until the SSIM
    if (grad)
      for (size_t k = 0; k < x.size(); ++k) g_l1[k] += g_ssim[k];
  }
  const double inv_s = 1.0 / static_cast<double>(targets.size());
  l1 *= inv_s;
  const double ssim = SsimMean(x, targets, w, h, 3, grad ? &g_ssim : nullptr);
  if (grad) {
    grad->resize(x.size());
    const double l1_weight = (1 - o.lambda_dssim) * inv_s;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, x.size(), 1 << 14), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t k = r.begin(); k < r.end(); ++k) (*grad)[k] = T(l1_weight * g_l1[k] - o.lambda_dssim * g_ssim[k]);
    });
  }
  return (1 - o.lambda_dssim) * l1 + o.lambda_dssim * (1 - ssim);
}

template <typename T>
double PhotometricLoss(const std::vector<T>& x, const std::vector<T>& target, int w, int h,
                       const PhotometricLossOptions& o, std::vector<T>* grad) {
  return PhotometricLossMean(x, {&target}, w, h, o, grad);
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

namespace {

// PSNR of images in [0, 1] from their mean squared error.
double PsnrOfMse(double mse) {
  if (std::isnan(mse)) return mse;                    // a non-finite image has no PSNR (not 100 dB)
  return mse > 0 ? -10.0 * std::log10(mse) : 100.0;  // identical images: capped at 100 dB
}

}  // namespace

template <typename T>
double Psnr(const std::vector<T>& x, const std::vector<T>& target) {
  RequireSameSize(x.size(), target.size(), "psnr");
  double mse = 0;
  for (size_t k = 0; k < x.size(); ++k) mse += (static_cast<double>(x[k]) - target[k]) * (static_cast<double>(x[k]) - target[k]);
  return PsnrOfMse(mse / static_cast<double>(std::max<size_t>(1, x.size())));
}

double MaskedPsnr(const std::vector<float>& rgb, const std::vector<float>& target,
                  const std::vector<std::uint8_t>& valid) {
  if (valid.empty()) return Psnr(rgb, target);
  RequireSameSize(rgb.size(), target.size(), "masked psnr");
  RequireSameSize(rgb.size(), 3 * valid.size(), "masked psnr (valid, size)");
  double se = 0;
  std::size_t n = 0;
  for (std::size_t p = 0; p < valid.size(); ++p) {
    if (!valid[p]) continue;
    for (std::size_t k = 3 * p; k < 3 * p + 3; ++k) se += (static_cast<double>(rgb[k]) - target[k]) * (static_cast<double>(rgb[k]) - target[k]);
    n += 3;
  }
  if (n == 0) return std::numeric_limits<double>::quiet_NaN();
  return PsnrOfMse(se / static_cast<double>(n));
}

double HalfFittedPsnr(const std::vector<float>& render, const std::vector<float>& target, int width_px,
                      int height_px, const std::vector<std::uint8_t>& valid) {
  const std::size_t pixels = static_cast<std::size_t>(width_px) * static_cast<std::size_t>(height_px);
  RequireSameSize(render.size(), 3 * pixels, "half-fitted psnr (render, size)");
  RequireSameSize(target.size(), 3 * pixels, "half-fitted psnr (target, size)");
  if (!valid.empty()) RequireSameSize(valid.size(), pixels, "half-fitted psnr (valid, size)");
  const int half = width_px / 2;
  auto used = [&](std::size_t p) { return valid.empty() || valid[p]; };
  // Least-squares gain and offset per channel on the left half.
  LineFit fit[3];
  for (int y = 0; y < height_px; ++y)
    for (int x = 0; x < half; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * width_px + x;
      if (!used(p)) continue;
      for (int c = 0; c < 3; ++c) fit[c].Add(render[3 * p + c], target[3 * p + c]);
    }
  if (fit[0].n == 0) return std::numeric_limits<double>::quiet_NaN();
  double gain[3], offset[3];
  for (int c = 0; c < 3; ++c) {
    constexpr double kMinVariance = 1e-8;  // a flat channel: only its offset is fitted
    gain[c] = fit[c].VarianceA() > kMinVariance ? fit[c].Gain() : 1.0;
    offset[c] = fit[c].Offset(gain[c]);
  }
  double mse = 0, scored = 0;
  for (int y = 0; y < height_px; ++y)
    for (int x = half; x < width_px; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * width_px + x;
      if (!used(p)) continue;
      ++scored;
      for (int c = 0; c < 3; ++c) {
        const double a = std::clamp(gain[c] * render[3 * p + c] + offset[c], 0.0, 1.0);
        mse += (a - target[3 * p + c]) * (a - target[3 * p + c]);
      }
    }
  if (scored == 0) return std::numeric_limits<double>::quiet_NaN();
  return PsnrOfMse(mse / (3 * scored));
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

double SurfaceHeightLoss(const std::vector<float>& z_m, const std::vector<float>& surface_height_m,
                         const SurfaceHeightOptions& o, std::vector<float>* d_z, const std::vector<float>* weight) {
  RequireSameSize(surface_height_m.size(), z_m.size(), "surface height (heights, centres)");
  RequireSameSize(d_z->size(), z_m.size(), "surface height (gradient, centres)");
  if (weight) RequireSameSize(weight->size(), z_m.size(), "surface height (weights, centres)");
  if (z_m.empty() || o.lambda <= 0) return 0.0;
  const double scale = o.lambda / static_cast<double>(z_m.size());
  double loss = 0;
  for (std::size_t i = 0; i < z_m.size(); ++i) {
    const double e = static_cast<double>(z_m[i]) - surface_height_m[i];
    if (!(std::abs(e) < o.band_m)) continue;  // NaN height, or off the surface
    const double w = scale * (weight ? (*weight)[i] : 1.0f);
    loss += 0.5 * w * e * e;
    (*d_z)[i] += static_cast<float>(w * e);
  }
  return loss;
}

#define SKYFALL_INSTANTIATE_LOSSES(T)                                                                       \
  template double L1Loss(const std::vector<T>&, const std::vector<T>&, std::vector<T>*);                   \
  template double Ssim(const std::vector<T>&, const std::vector<T>&, int, int, int, std::vector<T>*);      \
  template double PhotometricLoss(const std::vector<T>&, const std::vector<T>&, int, int,                  \
                                  const PhotometricLossOptions&, std::vector<T>*);                        \
  template double SsimMean(const std::vector<T>&, const std::vector<const std::vector<T>*>&, int, int, int,  \
                           std::vector<T>*);                                                                \
  template double PhotometricLossMean(const std::vector<T>&, const std::vector<const std::vector<T>*>&, int, \
                                      int, const PhotometricLossOptions&, std::vector<T>*);                 \
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
