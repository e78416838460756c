#include "splat/density_control.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "core/error.h"
#include "splat/depth_prior.h"
#include "splat/rasterizer.h"
#include "splat/raster_test_support.h"

namespace skyfall {
namespace {

using testing::SmoothRasterOptions;

// One Gaussian: centre [m], standard deviations [m], opacity, grey colour.
void AddGaussian(GaussianCloud* c, const Eigen::Vector3f& centre, const Eigen::Vector3f& sigma_m, double opacity,
                 float grey, const Eigen::Quaternionf& rotation = Eigen::Quaternionf::Identity()) {
  c->means.push_back(centre);
  c->log_scales.push_back(sigma_m.array().log().matrix());
  c->rotations.emplace_back(rotation.w(), rotation.x(), rotation.y(), rotation.z());
  c->opacity_logits.push_back(static_cast<float>(std::log(opacity / (1 - opacity))));
  std::array<float, 3 * kShCoeffsPerChannel> sh{};
  for (int ch = 0; ch < 3; ++ch) sh[ch * kShCoeffsPerChannel] = static_cast<float>(ShDcFromColour(grey));
  c->sh.push_back(sh);
}

// Moments that name their Gaussian, so the test sees which one they follow.
GaussianCloud NumberedMoments(std::size_t n) {
  GaussianCloud m;
  for (std::size_t i = 0; i < n; ++i)
    AddGaussian(&m, Eigen::Vector3f::Constant(static_cast<float>(i)), Eigen::Vector3f::Ones(), 0.5, 0.5f);
  return m;
}

DensityControlOptions MergeOptions() {
  DensityControlOptions o;
  o.merge_within_m = 0.01;
  o.merge_interval_steps = 100;
  o.merge_max_shape_difference = 0.25;
  return o;
}

TEST(DensityControl, MergesCopiesOfOneGaussianAndKeepsOthers) {
  GaussianCloud c;
  const Eigen::Vector3f sigma(1.0f, 0.8f, 0.3f);
  AddGaussian(&c, {0, 0, 0}, sigma, 0.2, 0.2f);           // 0: a cluster of three,
  AddGaussian(&c, {20, 0, 0}, sigma, 0.5, 0.5f);          // 1: alone
  AddGaussian(&c, {0.004f, 0, 0}, sigma, 0.4, 0.6f);      // 2: 4 mm from 0
  AddGaussian(&c, {0, 0.004f, 0}, sigma * 3.0f, 0.5, 0.5f);  // 3: near 0 but three times as large
  AddGaussian(&c, {0, 0, -0.004f}, sigma, 0.6, 0.9f);     // 4: 4 mm below 0
  GaussianCloud m = NumberedMoments(c.size()), v = NumberedMoments(c.size());
  DensityControl dc(MergeOptions(), 100.0);
  dc.stats().Reset(c.size());
  dc.stats().grad_sum = {0, 1, 2, 3, 4};
  const std::vector<std::size_t> source = dc.MergeCoincident(&c, &m, &v);
  ASSERT_EQ(c.size(), 3u);
  // The merged Gaussian stands in the first member's place and carries the
  // most opaque member's (4) optimizer state and statistics.
  EXPECT_EQ(source, (std::vector<std::size_t>{4, 1, 3}));
  EXPECT_EQ(m.means[0], Eigen::Vector3f::Constant(4));
  EXPECT_EQ(v.means[2], Eigen::Vector3f::Constant(3));
  EXPECT_EQ(dc.stats().grad_sum, (std::vector<float>{4, 1, 3}));
  // Opacity: one minus the product of the members' transparencies.
  EXPECT_NEAR(OpacityOfLogit(c.opacity_logits[0]), 1 - 0.8 * 0.6 * 0.4, 1e-6);
  // Centre and colour: opacity-weighted means.
  const double w = 0.2 + 0.4 + 0.6;
  EXPECT_NEAR(c.means[0].x(), 0.4 * 0.004 / w, 1e-7);
  EXPECT_NEAR(c.means[0].z(), -0.6 * 0.004 / w, 1e-7);
  EXPECT_NEAR(c.sh[0][0], ShDcFromColour((0.2 * 0.2 + 0.4 * 0.6 + 0.6 * 0.9) / w), 1e-5);
  // Shape: the members' covariance, widened by their spread (millimetres, so
  // below 1e-4 of each axis).
  Eigen::Vector3f merged_sigma = c.log_scales[0].array().exp();
  std::sort(merged_sigma.data(), merged_sigma.data() + 3);
  EXPECT_NEAR(merged_sigma[0], 0.3f, 1e-4);
  EXPECT_NEAR(merged_sigma[1], 0.8f, 1e-4);
  EXPECT_NEAR(merged_sigma[2], 1.0f, 1e-4);
  // The others are untouched.
  EXPECT_EQ(c.means[1], Eigen::Vector3f(20, 0, 0));
  EXPECT_NEAR(std::exp(c.log_scales[2].x()), 3.0f, 1e-6);
}

TEST(DensityControl, ARotatedCopyIsADifferentShape) {
  // Same scales, turned 90 degrees about the vertical: the covariances differ
  // by their whole size, so the two are not merged.
  GaussianCloud c;
  AddGaussian(&c, {0, 0, 0}, {2.0f, 0.5f, 0.5f}, 0.5, 0.5f);
  AddGaussian(&c, {0, 0, 0}, {2.0f, 0.5f, 0.5f}, 0.5, 0.5f,
              Eigen::Quaternionf(Eigen::AngleAxisf(static_cast<float>(M_PI / 2), Eigen::Vector3f::UnitZ())));
  GaussianCloud m = NumberedMoments(2), v = NumberedMoments(2);
  DensityControl dc(MergeOptions(), 100.0);
  dc.MergeCoincident(&c, &m, &v);
  EXPECT_EQ(c.size(), 2u);
}

// Two copies of a Gaussian with opacity a each composite to 1 - (1 - a g)^2
// where the footprint is g; the merged one gives (1 - (1 - a)^2) g. They
// agree at g = 0 and g = 1 and differ by a^2 g (1 - g) <= a^2 / 4 between,
// times the colour's contrast with the background.
TEST(DensityControl, AMergedPairRendersAsThePairWithinTheCompositingBound) {
  constexpr double kOpacity = 0.3;
  GaussianCloud pair;
  AddGaussian(&pair, {0, 0, 0}, {3.0f, 2.0f, 1.0f}, kOpacity, 0.9f);
  AddGaussian(&pair, {0.002f, -0.003f, 0.001f}, {3.0f, 2.0f, 1.0f}, kOpacity, 0.9f);
  GaussianCloud merged = pair, m = NumberedMoments(2), v = NumberedMoments(2);
  DensityControl dc(MergeOptions(), 100.0);
  dc.MergeCoincident(&merged, &m, &v);
  ASSERT_EQ(merged.size(), 1u);
  const PinholeCamera cam = NadirCamera(Eigen::Vector3d::Zero(), 0.25, 64, 500.0);
  const RasterOptions ro = SmoothRasterOptions();
  const RenderOutput<float> a = RenderGaussians(pair, cam, ro), b = RenderGaussians(merged, cam, ro);
  const double contrast = 0.9 - ro.background.minCoeff();
  const double bound = kOpacity * kOpacity / 4 * contrast;
  double worst = 0, centre_gap = 0;
  for (std::size_t k = 0; k < a.rgb.size(); ++k) worst = std::max(worst, std::abs(double(a.rgb[k]) - b.rgb[k]));
  const std::size_t centre = (32 * 64 + 32) * 3;
  centre_gap = std::abs(double(a.rgb[centre]) - b.rgb[centre]);
  std::printf("[figures] merged pair: worst colour difference %.4f (bound %.4f), at the centre %.5f\n", worst, bound,
              centre_gap);
  EXPECT_LE(worst, bound + 1e-4);  // + float rounding
  EXPECT_GT(worst, 0.2 * bound);   // the bound is tight: the render did change
  // The centre pixel lies an eighth of a metre from the centres, where g > 0.99,
  // so 4 g (1 - g) < 0.04 of the bound.
  EXPECT_LT(centre_gap, 0.04 * bound);
}

TEST(DensityControl, MergesOnItsIntervalButNeverOnTheLastStep) {
  DensityControlOptions o = MergeOptions();
  DensityControl dc(o, 100.0);
  EXPECT_FALSE(dc.MergeDue(50, 1000));
  EXPECT_TRUE(dc.MergeDue(100, 1000));
  EXPECT_TRUE(dc.MergeDue(900, 1000));
  EXPECT_FALSE(dc.MergeDue(1000, 1000));  // no steps left to mend what a merge changes
  o.merge_within_m = 0;
  EXPECT_FALSE(DensityControl(o, 100.0).MergeDue(100, 1000));
}

TEST(DensityControl, RefusesANegativeOrNonFiniteMergeRadius) {
  DensityControlOptions o = MergeOptions();
  o.merge_within_m = -0.01;
  EXPECT_THROW(o.Check(), Error);
  o.merge_within_m = std::numeric_limits<double>::infinity();
  EXPECT_THROW(o.Check(), Error);
  o.merge_within_m = 0;  // off
  EXPECT_NO_THROW(o.Check());
}

TEST(DensityControl, NonFiniteCentresAreLeftAlone) {
  GaussianCloud c;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  AddGaussian(&c, {nan, 0, 0}, {1, 1, 1}, 0.5, 0.5f);
  AddGaussian(&c, {nan, 0, 0}, {1, 1, 1}, 0.5, 0.5f);
  AddGaussian(&c, {0, 0, 0}, {1, 1, 1}, 0.5, 0.5f);
  GaussianCloud m = NumberedMoments(3), v = NumberedMoments(3);
  DensityControl dc(MergeOptions(), 100.0);
  dc.MergeCoincident(&c, &m, &v);
  EXPECT_EQ(c.size(), 3u);
}

}  // namespace
}  // namespace skyfall
