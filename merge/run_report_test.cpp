#include "merge/run_report.h"

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

}  // namespace
}  // namespace skyfall
