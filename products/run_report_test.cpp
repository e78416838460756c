#include "products/run_report.h"

#include <gtest/gtest.h>

#include "core/error.h"

namespace skyfall {
namespace {

const PixelBox kBounds{0, 0, 400, 300};
constexpr int kGap = 9;

TEST(PlaceLabels, ALoneLabelSitsRightOfItsPointAtItsLevel) {
  const auto boxes = PlaceLabels({{100, 150}}, {{60, 16}}, {}, kBounds, kGap);
  ASSERT_EQ(boxes.size(), 1u);
  EXPECT_EQ(boxes[0].x, 100 + kGap);
  EXPECT_EQ(boxes[0].y, 150 - 8);
}

TEST(PlaceLabels, ALabelThatWouldLeaveTheBoundsGoesLeft) {
  const auto boxes = PlaceLabels({{380, 150}}, {{60, 16}}, {}, kBounds, kGap);
  EXPECT_EQ(boxes[0].x, 380 - kGap - 60);
  EXPECT_TRUE(boxes[0].Inside(kBounds));
}

// Nine scenes with the same error and time (the benchmark's crowded case):
// every label readable, none over another or over a marker.
TEST(PlaceLabels, LabelsOfCoincidentPointsNeitherOverlapNorLeaveTheBounds) {
  std::vector<std::array<int, 2>> anchors(9, {200, 150}), sizes(9, {70, 16});
  const std::vector<PixelBox> markers{{194, 144, 12, 12}};
  const auto boxes = PlaceLabels(anchors, sizes, markers, kBounds, kGap);
  ASSERT_EQ(boxes.size(), 9u);
  for (std::size_t a = 0; a < boxes.size(); ++a) {
    EXPECT_TRUE(boxes[a].Inside(kBounds)) << a;
    EXPECT_FALSE(boxes[a].Overlaps(markers[0])) << a;
    for (std::size_t b = a + 1; b < boxes.size(); ++b) EXPECT_FALSE(boxes[a].Overlaps(boxes[b])) << a << " " << b;
  }
  // The first two take the level spots on either side; the rest step away
  // one label height at a time.
  EXPECT_EQ(boxes[0].y, boxes[1].y);
  EXPECT_NE(boxes[0].x, boxes[1].x);
}

TEST(PlaceLabels, AMarkerInTheWayMovesTheLabel) {
  const PixelBox marker{115, 140, 12, 12};
  const auto boxes = PlaceLabels({{100, 150}}, {{60, 16}}, {marker}, kBounds, kGap);
  EXPECT_FALSE(boxes[0].Overlaps(marker));
  EXPECT_EQ(boxes[0].x, 100 - kGap - 60);  // the level spot on the left is free
}

TEST(PlaceLabels, WhenNothingIsFreeTheLabelStaysRightOfItsPoint) {
  const PixelBox everything{0, 0, 400, 300};
  const auto boxes = PlaceLabels({{100, 150}}, {{60, 16}}, {everything}, kBounds, kGap);
  EXPECT_EQ(boxes[0].x, 100 + kGap);
  EXPECT_EQ(boxes[0].y, 150 - 8);
}

TEST(PlaceLabels, OneSizePerAnchorIsRequired) {
  EXPECT_THROW(PlaceLabels({{1, 1}, {2, 2}}, {{5, 5}}, {}, kBounds, kGap), Error);
}

TEST(NiceAxis, RoundStepsThatCoverTheRange) {
  const NiceAxis mae = NiceAxisOf(0.0, 2.76, 8);  // the 256 m benchmark's MAE axis
  EXPECT_DOUBLE_EQ(mae.step, 0.5);
  EXPECT_DOUBLE_EQ(mae.lo, 0.0);
  EXPECT_DOUBLE_EQ(mae.hi, 3.0);
  EXPECT_EQ(mae.Decimals(), 1);
  const NiceAxis seconds = NiceAxisOf(175.5, 276.0, 6);  // its time axis
  EXPECT_DOUBLE_EQ(seconds.step, 25.0);
  EXPECT_DOUBLE_EQ(seconds.lo, 175.0);
  EXPECT_DOUBLE_EQ(seconds.hi, 300.0);
  EXPECT_EQ(seconds.Decimals(), 0);
  EXPECT_EQ(NiceAxisOf(0.0, 0.9, 5).Decimals(), 2);  // steps of 0.25
}

TEST(NiceAxis, AnyRangeGetsANiceStepWithinTheTickCount) {
  for (double lo : {-3.7, 0.0, 0.004, 12.0, 1834.0})
    for (double span : {1e-3, 0.37, 1.0, 9.99, 260.0, 1.0e5})
      for (int max_ticks : {3, 5, 8}) {
        const NiceAxis a = NiceAxisOf(lo, lo + span, max_ticks);
        EXPECT_LE(a.lo, lo) << lo << " " << span;
        EXPECT_GE(a.hi, lo + span) << lo << " " << span;
        EXPECT_LE(std::lround((a.hi - a.lo) / a.step) + 1, max_ticks) << lo << " " << span << " " << max_ticks;
        const double mantissa = a.step / std::pow(10.0, std::floor(std::log10(a.step) + 1e-9));
        EXPECT_TRUE(std::abs(mantissa - 1) < 1e-9 || std::abs(mantissa - 2) < 1e-9 ||
                    std::abs(mantissa - 2.5) < 1e-9 || std::abs(mantissa - 5) < 1e-9)
            << a.step;
      }
  // An empty or reversed range still gives an axis.
  const NiceAxis flat = NiceAxisOf(5.0, 5.0, 6);
  EXPECT_GT(flat.hi, flat.lo);
}

}  // namespace
}  // namespace skyfall
