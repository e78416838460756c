#include "splat/lanes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace skyfall::lanes {
namespace {

using VF = Vec<float>;
using MF = Mask<float>;

TEST(Lanes, FloatExpIsWithinTwoUlpOfTheLibrary) {
  // Relative error against exp in double over the whole range the blending
  // can use (and beyond, up to the clamp at 88): 2.4e-7 is two float ulps
  // at 1.
  double worst = 0;
  for (double x = -87.0; x <= 87.99; x += 1.3e-3) {
    VF v;
    for (int i = 0; i < kLanes; ++i) v[i] = static_cast<float>(x + i * 2.7e-4);
    const VF e = Exp(v);
    for (int i = 0; i < kLanes; ++i) {
      const double truth = std::exp(static_cast<double>(v[i]));
      worst = std::max(worst, std::abs(e[i] - truth) / truth);
    }
  }
  EXPECT_LT(worst, 2.4e-7);
}

TEST(Lanes, FloatExpAtExtremes) {
  const float inf = std::numeric_limits<float>::infinity();
  const VF v = {-inf, -1000.0f, 0.0f, 1000.0f};
  const VF e = Exp(v);
  EXPECT_EQ(e[0], 0.0f);
  EXPECT_EQ(e[1], 0.0f);
  EXPECT_EQ(e[2], 1.0f);
  EXPECT_TRUE(std::isfinite(e[3]));  // clamped at e^88
  EXPECT_GT(e[3], 1e38f);
  // Exact at the integers' powers of two boundaries of the range reduction.
  const VF n = {-1.0f, 1.0f, -0.5f, 0.5f};
  const VF en = Exp(n);
  for (int i = 0; i < kLanes; ++i) EXPECT_NEAR(en[i], std::exp(n[i]), 2.4e-7 * std::exp(n[i]));
}

TEST(Lanes, DoubleExpIsTheLibrary) {
  Vec<double> v;
  for (int i = 0; i < kLanes; ++i) v[i] = -3.0 + 1.7 * i;
  const Vec<double> e = Exp(v);
  for (int i = 0; i < kLanes; ++i) EXPECT_EQ(e[i], std::exp(v[i]));
}

TEST(Lanes, MasksSelectCountAndSum) {
  const VF a = Iota<VF>();
  const MF odd = (Iota<MF>() & 1) != 0;
  EXPECT_TRUE(Any(odd));
  EXPECT_FALSE(Any(a < 0.0f));
  EXPECT_EQ(Count(odd), kLanes / 2);
  const VF s = Select(odd, a, Splat<VF>(-1.0f));
  for (int i = 0; i < kLanes; ++i) EXPECT_EQ(s[i], i % 2 ? static_cast<float>(i) : -1.0f);
  EXPECT_EQ(Sum(a), kLanes * (kLanes - 1) / 2);
  float buffer[kLanes + 1] = {};
  Store(buffer + 1, a);  // unaligned
  const VF back = Load<VF>(buffer + 1);
  for (int i = 0; i < kLanes; ++i) EXPECT_EQ(back[i], a[i]);
}

}  // namespace
}  // namespace skyfall::lanes
