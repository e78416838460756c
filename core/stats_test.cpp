#include "core/stats.h"

#include <gtest/gtest.h>

namespace skyfall {
namespace {

TEST(Stats, QuantileIsTheElementOfRankFloorPn) {
  const std::vector<double> v = {5, 1, 4, 2, 3};
  EXPECT_EQ(Quantile(v, 0.0), 1.0);
  EXPECT_EQ(Quantile(v, 0.39), 2.0);  // floor(1.95) = rank 1
  EXPECT_EQ(Quantile(v, 0.4), 3.0);   // rank 2
  EXPECT_EQ(Quantile(v, 0.999), 5.0);
  EXPECT_EQ(Quantile(v, 1.0), 5.0);   // clamped to the last rank
  EXPECT_EQ(Median(v), 3.0);
  EXPECT_EQ(Median(std::vector<float>{4, 1, 3, 2}), 3.0f);  // upper median of an even sample
  EXPECT_EQ(Median(std::vector<double>{}), 0.0);
}

}  // namespace
}  // namespace skyfall
