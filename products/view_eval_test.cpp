#include "products/view_eval.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "splat/losses.h"

namespace skyfall {
namespace {

std::vector<float> Texture(int w, int h) {
  std::vector<float> rgb;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) rgb.push_back(0.5f + 0.3f * std::sin(0.3f * x + c) * std::cos(0.2f * y));
  return rgb;
}

TEST(ViewEval, MaskedPsnrAndSsimMeasureOnlyTheMaskedPixels) {
  const int w = 48, h = 40;
  const std::vector<float> truth = Texture(w, h);
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(w) * h, 1);
  EXPECT_NEAR(MaskedSsim(truth, truth, mask, w, h), 1.0, 1e-6);
  // A constant error of 0.1 everywhere: PSNR = 20 dB exactly.
  std::vector<float> shifted = truth;
  for (float& v : shifted) v += 0.1f;
  EXPECT_NEAR(MaskedPsnr(shifted, truth, mask), 20.0, 1e-4);
  // Garbage outside the mask does not count.
  std::vector<float> spoiled = shifted;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w / 2; ++x) {
      mask[static_cast<std::size_t>(y) * w + x] = 0;
      for (int c = 0; c < 3; ++c) spoiled[3 * (static_cast<std::size_t>(y) * w + x) + c] = 1.0f;
    }
  EXPECT_NEAR(MaskedPsnr(spoiled, truth, mask), 20.0, 1e-4);
  // Noise lowers SSIM below 1; a flat grey image lowers it further.
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  std::vector<float> noisy = truth, flat(truth.size(), 0.5f);
  for (float& v : noisy) v += noise(rng);
  const double ssim_noisy = MaskedSsim(noisy, truth, mask, w, h), ssim_flat = MaskedSsim(flat, truth, mask, w, h);
  EXPECT_LT(ssim_noisy, 0.99);
  EXPECT_GT(ssim_noisy, ssim_flat);
  EXPECT_TRUE(std::isnan(MaskedPsnr(truth, truth, std::vector<std::uint8_t>(mask.size(), 0))));
}

}  // namespace
}  // namespace skyfall
