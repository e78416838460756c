#include "splat/losses.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>

#include "core/error.h"

namespace skyfall {
namespace {

std::vector<double> RandomImage(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  std::vector<double> v(n);
  for (auto& x : v) x = u(rng);
  return v;
}

// Central differences of `f` at every entry of `x` against `grad`.
void CheckGradient(std::vector<double> x, const std::function<double(const std::vector<double>&)>& f,
                   const std::vector<double>& grad, double step, double tol) {
  ASSERT_EQ(x.size(), grad.size());
  for (size_t k = 0; k < x.size(); ++k) {
    const double keep = x[k];
    x[k] = keep + step;
    const double fp = f(x);
    x[k] = keep - step;
    const double fm = f(x);
    x[k] = keep;
    EXPECT_NEAR(grad[k], (fp - fm) / (2 * step), tol * (1 + std::abs(grad[k]))) << "entry " << k;
  }
}

TEST(Losses, SsimGradientMatchesFiniteDifferences) {
  // Larger than the 11x11 window, with borders; and narrower than it.
  for (const auto& [w, h] : {std::pair{14, 12}, std::pair{6, 5}}) {
    const auto x = RandomImage(w * h * 3, 1), y = RandomImage(w * h * 3, 2);
    std::vector<double> grad;
    Ssim(x, y, w, h, 3, &grad);
    CheckGradient(x, [&](const std::vector<double>& v) { return Ssim<double>(v, y, w, h, 3, nullptr); }, grad,
                  1e-6, 1e-6);
    EXPECT_NEAR(Ssim<double>(x, x, w, h, 3, nullptr), 1.0, 1e-12);
  }
}

// A pixel's SSIM terms against central differences, at random statistics
// and where a numerator is exactly 0: a training tile met 2 cov + c2 == 0 in
// float (cov = -0.00045), where ssim / (2 cov + c2) was 0 / 0 and poisoned
// two Gaussians.
TEST(Losses, SsimAtPixelDerivativesAreFiniteWhereANumeratorIsZero) {
  constexpr float kC1 = 0.01f * 0.01f, kC2 = 0.03f * 0.03f;
  constexpr double kStep = 1e-7, kTol = 1e-6;
  auto check = [&](double mu_a, double mu_b, double va, double vb, double cov) {
    const SsimTerms<double> t = SsimAtPixel<double>(mu_a, mu_b, va, vb, cov, kC1, kC2);
    auto ssim = [&](double m, double v, double c) { return SsimAtPixel<double>(m, mu_b, v, vb, c, kC1, kC2).ssim; };
    const double fd_mu = (ssim(mu_a + kStep, va, cov) - ssim(mu_a - kStep, va, cov)) / (2 * kStep);
    const double fd_var = (ssim(mu_a, va + kStep, cov) - ssim(mu_a, va - kStep, cov)) / (2 * kStep);
    const double fd_cov = (ssim(mu_a, va, cov + kStep) - ssim(mu_a, va, cov - kStep)) / (2 * kStep);
    EXPECT_NEAR(t.d_mu_a, fd_mu, kTol * (1 + std::abs(fd_mu)));
    EXPECT_NEAR(t.d_var_a, fd_var, kTol * (1 + std::abs(fd_var)));
    EXPECT_NEAR(t.d_cov, fd_cov, kTol * (1 + std::abs(fd_cov)));
  };
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> mu(0.0, 1.0), var(0.0, 0.05), cov(-0.02, 0.02);
  for (int k = 0; k < 50; ++k) check(mu(rng), mu(rng), var(rng), var(rng), cov(rng));
  check(0.3, 0.6, 0.000329, 0.0073, -0.5 * kC2);  // 2 cov + c2 == 0
  check(0.01, -0.5 * kC1 / 0.01, 0.001, 0.002, 0.0005);  // 2 mu_a mu_b + c1 == 0

  // In float, as training runs, exactly at the zero: finite and right.
  const SsimTerms<float> f = SsimAtPixel<float>(0.3f, 0.6f, 0.000329173f, 0.00730032f, -0.5f * kC2, kC1, kC2);
  EXPECT_EQ(f.ssim, 0.0f);
  EXPECT_TRUE(std::isfinite(f.d_mu_a) && std::isfinite(f.d_var_a) && std::isfinite(f.d_cov));
  const SsimTerms<double> d = SsimAtPixel<double>(0.3, 0.6, 0.000329173, 0.00730032, -0.5 * kC2, kC1, kC2);
  EXPECT_NEAR(f.d_cov, d.d_cov, 1e-5 * std::abs(d.d_cov));
  EXPECT_NEAR(f.d_mu_a, d.d_mu_a, 1e-5 * (1 + std::abs(d.d_mu_a)));
}

// Training evaluates SSIM in float. Against double on the same image:
// values to 1e-5 and gradients to 1e-3 of the largest gradient (float keeps
// about 7 digits; the variances E[a^2] - mu^2 lose about 3 of them where the
// image is flat, which C2 = 9e-4 keeps from mattering).
TEST(Losses, FloatSsimFollowsDoubleAtAnySize) {
  constexpr double kValueTol = 1e-5, kGradientTol = 1e-3;
  for (const auto& [w, h] : {std::pair{64, 48}, std::pair{6, 5}, std::pair{11, 1}, std::pair{1, 13}}) {
    const auto x = RandomImage(w * h * 3, 11), y = RandomImage(w * h * 3, 12);
    const std::vector<float> xf(x.begin(), x.end()), yf(y.begin(), y.end());
    std::vector<double> grad;
    std::vector<float> grad_f;
    const double s = Ssim(x, y, w, h, 3, &grad), s_f = Ssim(xf, yf, w, h, 3, &grad_f);
    EXPECT_NEAR(s_f, s, kValueTol) << w << "x" << h;
    double largest = 0;
    for (double g : grad) largest = std::max(largest, std::abs(g));
    for (size_t k = 0; k < grad.size(); ++k) ASSERT_NEAR(grad_f[k], grad[k], kGradientTol * largest) << w << "x" << h << " entry " << k;
  }
}

TEST(Losses, MeanOverTargetsEqualsTheMeanOfEachTargetsLossAndGradient) {
  // The shared-blur form against one call per target, and its gradient
  // against finite differences.
  const int w = 13, h = 12;
  auto x = RandomImage(w * h * 3, 21);
  const auto y1 = RandomImage(w * h * 3, 22), y2 = RandomImage(w * h * 3, 23), y3 = RandomImage(w * h * 3, 24);
  for (size_t k = 0; k < x.size(); ++k)
    for (const auto* y : {&y1, &y2, &y3})
      if (std::abs(x[k] - (*y)[k]) < 1e-3) x[k] += 2e-3;  // away from the L1 kinks
  const std::vector<const std::vector<double>*> targets = {&y1, &y2, &y3};
  const PhotometricLossOptions o;
  std::vector<double> grad, g1, g2, g3;
  const double mean = PhotometricLossMean(x, targets, w, h, o, &grad);
  const double each = (PhotometricLoss(x, y1, w, h, o, &g1) + PhotometricLoss(x, y2, w, h, o, &g2) +
                       PhotometricLoss(x, y3, w, h, o, &g3)) / 3;
  EXPECT_NEAR(mean, each, 1e-12);
  for (size_t k = 0; k < x.size(); ++k) ASSERT_NEAR(grad[k], (g1[k] + g2[k] + g3[k]) / 3, 1e-12) << k;
  CheckGradient(x, [&](const std::vector<double>& v) { return PhotometricLossMean<double>(v, targets, w, h, o, nullptr); },
                grad, 1e-7, 1e-6);
  std::vector<double> gs;
  EXPECT_NEAR(SsimMean(x, targets, w, h, 3, &gs),
              (Ssim<double>(x, y1, w, h, 3, nullptr) + Ssim<double>(x, y2, w, h, 3, nullptr) +
               Ssim<double>(x, y3, w, h, 3, nullptr)) / 3, 1e-12);
  EXPECT_THROW(SsimMean<double>(x, {}, w, h, 3, &gs), Error);
}

TEST(Losses, PhotometricLossGradientAwayFromL1Kinks) {
  const int w = 12, h = 11;
  auto x = RandomImage(w * h * 3, 3);
  const auto y = RandomImage(w * h * 3, 4);
  for (size_t k = 0; k < x.size(); ++k)
    if (std::abs(x[k] - y[k]) < 1e-3) x[k] += 2e-3;  // |.| is not differentiable at 0
  std::vector<double> grad;
  const PhotometricLossOptions o;
  PhotometricLoss(x, y, w, h, o, &grad);
  CheckGradient(x, [&](const std::vector<double>& v) { return PhotometricLoss<double>(v, y, w, h, o, nullptr); },
                grad, 1e-7, 1e-6);
}

TEST(Losses, OpacityEntropyIsSafeAtZeroAndOne) {
  const std::vector<double> logits = {-800.0, -40.0, -3.0, -0.2, 0.0, 0.7, 5.0, 40.0, 800.0};
  std::vector<double> grad;
  const double e = OpacityEntropy(logits, &grad);
  EXPECT_TRUE(std::isfinite(e));
  for (double g : grad) EXPECT_TRUE(std::isfinite(g));
  // Saturated opacities carry (almost) no entropy and no gradient.
  EXPECT_EQ(grad[0], 0.0);
  EXPECT_EQ(grad[8], 0.0);
  EXPECT_NEAR(OpacityEntropy<double>({0.0}, nullptr), std::log(2.0), 1e-15);  // maximum, at a = 0.5
  CheckGradient(logits, [](const std::vector<double>& v) { return OpacityEntropy<double>(v, nullptr); }, grad,
                1e-6, 1e-7);
}

TEST(Losses, PearsonDepthGradientAndZeroVariance) {
  const int n = 40;
  auto depth = RandomImage(n, 5), prior = RandomImage(n, 6);
  std::vector<unsigned char> valid(n, 1);
  valid[3] = valid[17] = 0;
  std::vector<double> grad;
  const double l = PearsonDepthLoss(depth, prior, valid, &grad);
  EXPECT_GT(l, 0.0);
  EXPECT_LT(l, 2.0);
  EXPECT_EQ(grad[3], 0.0);
  CheckGradient(depth, [&](const std::vector<double>& v) { return PearsonDepthLoss<double>(v, prior, valid, nullptr); },
                grad, 1e-7, 1e-6);
  // Perfectly correlated up to scale and shift: zero loss.
  std::vector<double> affine(n);
  for (int k = 0; k < n; ++k) affine[k] = 3.0 * prior[k] - 7.0;
  EXPECT_NEAR(PearsonDepthLoss<double>(affine, prior, valid, nullptr), 0.0, 1e-12);
  // Anti-correlated (a disparity-like prior) is as good: |r| = 1.
  for (int k = 0; k < n; ++k) affine[k] = -0.5 * prior[k] + 2.0;
  EXPECT_NEAR(PearsonDepthLoss<double>(affine, prior, valid, nullptr), 0.0, 1e-12);
  // The gradient also holds where r < 0.
  std::vector<double> anti(n);
  for (int k = 0; k < n; ++k) anti[k] = -prior[k] + 0.3 * depth[k];
  PearsonDepthLoss(anti, prior, valid, &grad);
  CheckGradient(anti, [&](const std::vector<double>& v) { return PearsonDepthLoss<double>(v, prior, valid, nullptr); },
                grad, 1e-7, 1e-6);
  // Flat render (zero variance): defined as no supervision.
  const std::vector<double> flat(n, 12.5);
  EXPECT_EQ(PearsonDepthLoss(flat, prior, valid, &grad), 0.0);
  for (double g : grad) EXPECT_EQ(g, 0.0);
  EXPECT_EQ(PearsonDepthLoss<double>(prior, flat, valid, nullptr), 0.0);
}

TEST(Losses, SurfaceAnchorGradientsMatchFiniteDifferences) {
  // Depth errors inside and beyond the Huber scale, a pixel too transparent
  // for its depth to count, and pixels that do not see the surface.
  const std::vector<double> target = {10.0, 10.0, -3.0, 4.0, 0.0, 7.5};
  const std::vector<double> depth = {10.4, 12.5, -7.0, 4.0, 9.0, 0.0};
  const std::vector<double> alpha = {0.9, 0.6, 0.7, 0.05, 0.8, 0.3};
  const std::vector<unsigned char> valid = {1, 1, 1, 1, 0, 1};
  const SurfaceAnchorOptions o{0.2, 0.3, 1.0, 0.1};
  std::vector<double> d_depth, d_alpha, unused_a, unused_b;
  const double l = SurfaceAnchorLoss(depth, alpha, target, valid, o, &d_depth, &d_alpha);
  // By hand over the 5 valid pixels: Huber 0.08, 2.0, 3.5, (too transparent),
  // (5th: 7.5 m off at alpha 0.3: 7.0); opacity 0.1 + 0.4 + 0.3 + 0.95 + 0.7.
  EXPECT_NEAR(l, (0.2 * (0.08 + 2.0 + 3.5 + 7.0) + 0.3 * (0.1 + 0.4 + 0.3 + 0.95 + 0.7)) / 5, 1e-12);
  EXPECT_EQ(d_depth[3], 0.0);
  EXPECT_EQ(d_depth[4], 0.0);
  EXPECT_EQ(d_alpha[4], 0.0);
  CheckGradient(depth, [&](const std::vector<double>& v) {
    return SurfaceAnchorLoss(v, alpha, target, valid, o, &unused_a, &unused_b);
  }, d_depth, 1e-7, 1e-6);
  CheckGradient(alpha, [&](const std::vector<double>& v) {
    return SurfaceAnchorLoss(depth, v, target, valid, o, &unused_a, &unused_b);
  }, d_alpha, 1e-7, 1e-6);
  // Nothing sees the surface: no loss, no pull.
  EXPECT_EQ(SurfaceAnchorLoss(depth, alpha, target, std::vector<unsigned char>(6, 0), o, &d_depth, &d_alpha), 0.0);
  for (double g : d_alpha) EXPECT_EQ(g, 0.0);
}

TEST(Losses, SurfaceHeightHoldsCentresWithinTheBandAndMatchesFiniteDifferences) {
  // On the surface, 0.3 m above, 0.4 m below with half confidence, 2 m
  // above (a wall: beyond the 1 m band), over no surface (NaN).
  const std::vector<double> z = {5.0, 5.3, 11.6, 7.0, 3.0};
  const std::vector<float> height = {5.0f, 5.0f, 12.0f, 5.0f, NAN};
  const std::vector<float> weight = {1.0f, 1.0f, 0.5f, 1.0f, 1.0f};
  const SurfaceHeightOptions o{2.0, 1.0};
  auto loss = [&](const std::vector<double>& v, std::vector<float>* d_z) {
    const std::vector<float> zf(v.begin(), v.end());
    std::vector<float> unused(v.size(), 0.0f);
    return SurfaceHeightLoss(zf, height, o, d_z ? d_z : &unused, &weight);
  };
  std::vector<float> d_z(z.size(), 0.0f);
  const double l = loss(z, &d_z);
  // By hand: 2 / 5 * 0.5 * (0.3^2 + 0.5 * 0.4^2).
  EXPECT_NEAR(l, 0.2 * (0.09 + 0.08), 1e-6);
  EXPECT_EQ(d_z[0], 0.0f);
  EXPECT_EQ(d_z[3], 0.0f);
  EXPECT_EQ(d_z[4], 0.0f);
  // Float centres: a 1e-3 m step keeps the difference quotient within ~1e-4
  // of the derivative (rounding ~6e-8 * 0.03 / 1e-3), so 1e-3 is ample.
  constexpr double kStepM = 1e-3, kTol = 1e-3;
  CheckGradient(z, [&](const std::vector<double>& v) { return loss(v, nullptr); },
                std::vector<double>(d_z.begin(), d_z.end()), kStepM, kTol);
  // The gradient adds to what is there; a size mismatch is an error.
  std::vector<float> d_more(z.size(), 1.0f);
  loss(z, &d_more);
  EXPECT_NEAR(d_more[1], 1.0f + d_z[1], 1e-6);
  std::vector<float> short_grad(2, 0.0f);
  EXPECT_THROW(SurfaceHeightLoss(std::vector<float>(z.begin(), z.end()), height, o, &short_grad), Error);
}

TEST(Losses, SurfaceAnchorDepthWeightsScaleOnlyTheDepthTerm) {
  const std::vector<double> target = {10.0, 10.0, -3.0, 7.5};
  const std::vector<double> depth = {10.4, 12.5, -7.0, 0.0};
  const std::vector<double> alpha = {0.9, 0.6, 0.7, 0.3};
  const std::vector<unsigned char> valid(4, 1);
  const std::vector<float> weight = {1.0f, 0.5f, 0.0f, 0.25f};
  const SurfaceAnchorOptions o{0.2, 0.3, 1.0, 0.1};
  std::vector<double> d_depth, d_alpha, unused_a, unused_b;
  const double l = SurfaceAnchorLoss(depth, alpha, target, valid, o, &d_depth, &d_alpha, &weight);
  // Huber 0.08, 2.0, 3.5, 7.0 weighted 1, 0.5, 0, 0.25; opacity unweighted.
  EXPECT_NEAR(l, (0.2 * (0.08 + 1.0 + 0.0 + 1.75) + 0.3 * (0.1 + 0.4 + 0.3 + 0.7)) / 4, 1e-12);
  EXPECT_EQ(d_depth[2], 0.0);  // no confidence: no pull on the depth
  EXPECT_NE(d_alpha[2], 0.0);  // but the surface is still there to cover
  CheckGradient(depth, [&](const std::vector<double>& v) {
    return SurfaceAnchorLoss(v, alpha, target, valid, o, &unused_a, &unused_b, &weight);
  }, d_depth, 1e-7, 1e-6);
  CheckGradient(alpha, [&](const std::vector<double>& v) {
    return SurfaceAnchorLoss(depth, v, target, valid, o, &unused_a, &unused_b, &weight);
  }, d_alpha, 1e-7, 1e-6);
  const std::vector<float> short_weight(3, 1.0f);
  EXPECT_THROW(SurfaceAnchorLoss(depth, alpha, target, valid, o, &d_depth, &d_alpha, &short_weight), Error);
}

TEST(Losses, PsnrOfKnownError) {
  const std::vector<float> a(100, 0.5f), b(100, 0.6f);
  EXPECT_NEAR(Psnr(a, b), 20.0, 1e-4);  // MSE 0.01
  std::vector<float> c = a;
  c[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(std::isnan(Psnr(c, b)));  // not the 100 dB of identical images
}

// Pixels without data do not count: a view whose crop runs past its image
// (zeros there) scores as its data does.
TEST(Losses, MaskedPsnrLeavesPixelsWithoutDataOut) {
  std::vector<float> render(3 * 10, 0.5f), target(3 * 10, 0.6f);
  EXPECT_NEAR(MaskedPsnr(render, target, {}), Psnr(render, target), 1e-12);  // no mask: every pixel
  std::vector<std::uint8_t> valid(10, 1);
  for (int p = 7; p < 10; ++p) {
    valid[p] = 0;
    for (int c = 0; c < 3; ++c) target[3 * p + c] = 0.0f;  // zero fill beyond the image
  }
  EXPECT_NEAR(MaskedPsnr(render, target, valid), 20.0, 1e-4);  // MSE 0.01 on the valid pixels
  EXPECT_LT(Psnr(render, target), 15.0);                       // the zero fill counted: MSE 0.082
  EXPECT_TRUE(std::isnan(MaskedPsnr(render, target, std::vector<std::uint8_t>(10, 0))));
  EXPECT_THROW(MaskedPsnr(render, target, std::vector<std::uint8_t>(9, 1)), Error);
}

// A render that is the truth seen through a per-channel gain and offset (a
// different date) scores as perfect once the affine is fitted on the left
// half; an error confined to the left half does not count; one on the right
// half does, at its known MSE; an all-masked half, or a non-finite
// render, gives NaN.
TEST(Losses, HalfFittedPsnrFitsTheLeftHalfAndScoresTheRight) {
  const int w = 8, h = 4;
  std::vector<float> truth(3 * w * h), render(truth.size());
  for (int p = 0; p < w * h; ++p)
    for (int c = 0; c < 3; ++c) {
      truth[3 * p + c] = 0.1f + 0.8f * static_cast<float>((p * 7 + c * 3) % 11) / 10.0f;
      render[3 * p + c] = (truth[3 * p + c] - 0.05f * c) / (1.5f + 0.2f * c);  // truth = gain * render + offset
    }
  EXPECT_LT(Psnr(render, truth), 20.0);
  EXPECT_GT(HalfFittedPsnr(render, truth, w, h), 90.0);  // float round-off only
  std::vector<float> left_wrong = render;
  for (int y = 0; y < h; ++y) left_wrong[3 * (y * w + 1)] += 0.3f;  // outliers in the fitting half
  EXPECT_LT(HalfFittedPsnr(left_wrong, truth, w, h), 90.0);         // they bend the fit a little
  std::vector<float> truth_off = truth;
  for (int y = 0; y < h; ++y)
    for (int x = w / 2; x < w; ++x) truth_off[3 * (y * w + x)] += 0.1f;  // red 0.1 off on the right half
  // MSE over the scored half: 0.01 on one channel of three.
  EXPECT_NEAR(HalfFittedPsnr(render, truth_off, w, h), -10.0 * std::log10(0.01 / 3), 1e-3);
  std::vector<std::uint8_t> valid(w * h, 1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w / 2; ++x) valid[y * w + x] = 0;
  EXPECT_TRUE(std::isnan(HalfFittedPsnr(render, truth, w, h, valid)));
  EXPECT_THROW(HalfFittedPsnr(render, truth, w + 1, h), Error);
  std::vector<float> broken = render;
  broken[3 * 1] = std::numeric_limits<float>::quiet_NaN();  // a non-finite pixel in the fitting half
  EXPECT_TRUE(std::isnan(HalfFittedPsnr(broken, truth, w, h)));  // not the 100 dB of a perfect fit
}

}  // namespace
}  // namespace skyfall
