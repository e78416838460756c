#include "splat/gaussian_spill.h"

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

GaussianCloud Numbered(std::size_t n) {
  GaussianCloud c;
  c.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    c.means[i] = Eigen::Vector3f(static_cast<float>(i), 0.5f, -2.0f);
    c.log_scales[i] = Eigen::Vector3f(-1.0f, -2.0f, 0.001f * i);
    c.rotations[i] = Eigen::Vector4f(1.0f, 0.0f, 0.1f, 0.0f);
    c.opacity_logits[i] = static_cast<float>(i % 9) - 4;
    for (int k = 0; k < 12; ++k) c.sh[i][k] = 0.01f * k + i;
  }
  return c;
}

// Every budget, from flushing at each record to never flushing, gives each
// key its records, whole and in the order added, with their tags.
TEST(GaussianSpill, EachKeyGetsItsRecordsInOrderWhateverTheBudget) {
  const GaussianCloud c = Numbered(1000);
  for (std::size_t budget : {std::size_t{1}, std::size_t{5000}, std::size_t{1} << 30}) {
    const fs::path dir = ScratchDir("spill") / "s";
    {
      KeyedSpill spill(dir, kSpilledGaussianBytes, budget);
      for (std::size_t i = 0; i < c.size(); ++i) SpillGaussian(spill, std::to_string(i % 3), c, i, 7 * i);
      EXPECT_EQ(spill.keys(), (std::set<std::string>{"0", "1", "2"}));
      for (int key = 0; key < 3; ++key) {
        std::vector<std::uint64_t> tags;
        const GaussianCloud back = ReadSpilledGaussians(spill, std::to_string(key), &tags);
        ASSERT_EQ(back.size(), key == 0 ? 334u : 333u) << budget;
        for (std::size_t j = 0; j < back.size(); ++j) {
          const std::size_t i = 3 * j + key;
          EXPECT_EQ(back.means[j], c.means[i]);
          EXPECT_EQ(back.log_scales[j], c.log_scales[i]);
          EXPECT_EQ(back.rotations[j], c.rotations[i]);
          EXPECT_EQ(back.opacity_logits[j], c.opacity_logits[i]);
          EXPECT_EQ(back.sh[j], c.sh[i]);
          EXPECT_EQ(tags[j], 7 * i);
        }
      }
      spill.Remove("1");
      EXPECT_EQ(spill.keys(), (std::set<std::string>{"0", "2"}));
      EXPECT_EQ(ReadSpilledGaussians(spill, "1").size(), 0u);
      EXPECT_EQ(ReadSpilledGaussians(spill, "2").size(), 333u);
    }
    EXPECT_FALSE(fs::exists(dir));  // removed with the spill
  }
}

TEST(GaussianSpill, ARecordOfAnotherSizeIsRefused) {
  KeyedSpill spill(ScratchDir("spill_size") / "s", 24, 1 << 20);
  const std::array<float, 6> record{1, 2, 3, 4, 5, 6};
  spill.Add("a", record.data());
  EXPECT_EQ(spill.Read("a").size(), 24u);
  EXPECT_THROW(ReadSpilledGaussians(spill, "a"), Error);
  EXPECT_THROW(SpillGaussian(spill, "a", Numbered(1), 0), Error);
}

}  // namespace
}  // namespace skyfall
