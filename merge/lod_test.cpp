#include "merge/lod.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>

#include "core/atomic_file.h"
#include "core/error.h"
#include "splat/ply.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

// Scene parameters are stored in float: masses and means recomputed from
// them agree to float round-off (~1e-7 relative), accumulated over
// thousands of Gaussians.
constexpr double kMassRelTol = 1e-5;
constexpr double kMeanTolM = 1e-3;

GaussianCloud RandomCloud(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> pos(-32, 32), log_s(std::log(0.05f), std::log(0.3f)), logit(-3.0f, -1.0f),
      unit(-1, 1);
  GaussianCloud c;
  for (std::size_t i = 0; i < n; ++i) {
    c.means.emplace_back(pos(rng), pos(rng), 0.1f * pos(rng));
    c.log_scales.emplace_back(log_s(rng), log_s(rng), log_s(rng));
    c.rotations.emplace_back(Eigen::Vector4f(unit(rng), unit(rng), unit(rng), unit(rng)).normalized());
    c.opacity_logits.push_back(logit(rng));
    std::array<float, 12> sh;
    for (float& v : sh) v = unit(rng);
    c.sh.push_back(sh);
  }
  return c;
}

struct Moments {
  double mass = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double sh0 = 0;  // mass-weighted red DC
};

Moments MomentsOf(const GaussianCloud& c) {
  Moments m;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const double w = GaussianMass(c, i);
    m.mass += w;
    m.mean += w * c.means[i].cast<double>();
    m.sh0 += w * c.sh[i][0];
  }
  m.mean /= m.mass;
  m.sh0 /= m.mass;
  return m;
}

TEST(Lod, MergingTwoGaussiansMatchesTheMixtureMoments) {
  GaussianCloud c = RandomCloud(2, 3);
  c.rotations[0] = {1, 0, 0, 0};
  c.rotations[1] = {1, 0, 0, 0};
  c.log_scales[0] = Eigen::Vector3f(std::log(0.2f), std::log(0.1f), std::log(0.3f));
  c.log_scales[1] = Eigen::Vector3f(std::log(0.1f), std::log(0.2f), std::log(0.1f));
  c.means[0] = {0, 0, 0};
  c.means[1] = {1, 0, 0};
  GaussianCloud out;
  ASSERT_TRUE(MergeGaussians(c, {0, 1}, &out));
  const double m0 = GaussianMass(c, 0), m1 = GaussianMass(c, 1), m = m0 + m1;
  const double mx = m1 / m;  // mean x
  // Mixture covariance: weighted member covariances plus the spread of means.
  const double var_x = (m0 * 0.04 + m1 * 0.01) / m + (m0 * mx * mx + m1 * (1 - mx) * (1 - mx)) / m;
  const double var_y = (m0 * 0.01 + m1 * 0.04) / m, var_z = (m0 * 0.09 + m1 * 0.01) / m;
  EXPECT_NEAR(out.means[0].x(), mx, 1e-6);
  Eigen::Vector3d sigma = out.log_scales[0].cast<double>().array().exp();
  std::sort(sigma.data(), sigma.data() + 3);
  Eigen::Vector3d expected(std::sqrt(var_x), std::sqrt(var_y), std::sqrt(var_z));
  std::sort(expected.data(), expected.data() + 3);
  EXPECT_NEAR((sigma - expected).norm(), 0.0, 1e-5);
  EXPECT_NEAR(GaussianMass(out, 0), m, 1e-6 * m);
  // The merged rotation is a proper rotation (unit quaternion).
  EXPECT_NEAR(out.rotations[0].norm(), 1.0, 1e-6);
}

TEST(Lod, EveryLevelPreservesMassAndMeanAndBoundsItsError) {
  const GaussianCloud finest = RandomCloud(20000, 7);
  LodOptions o;
  o.base_voxel_m = 0.5;  // too fine to merge anything: the first levels come from doubled voxels
  o.max_levels = 5;
  const std::vector<LodLevel> levels = BuildLod(o, finest);
  ASSERT_GE(levels.size(), 4u);
  const Moments ref = MomentsOf(finest);
  EXPECT_EQ(levels[0].cloud.size(), finest.size());  // the finest level is the scene itself
  EXPECT_EQ(levels[0].geometric_error_m, 0.0);
  for (std::size_t k = 1; k < levels.size(); ++k) {
    const LodLevel& l = levels[k];
    SCOPED_TRACE("level " + std::to_string(k));
    EXPECT_EQ(l.saturated, 0u);
    const Moments got = MomentsOf(l.cloud);
    EXPECT_NEAR(got.mass, ref.mass, kMassRelTol * ref.mass);
    EXPECT_NEAR((got.mean - ref.mean).norm(), 0.0, kMeanTolM);
    EXPECT_NEAR(got.sh0, ref.sh0, 1e-4);
    EXPECT_LT(l.cloud.size(), levels[k - 1].cloud.size());
    EXPECT_LE(static_cast<double>(l.cloud.size()), o.min_reduction * levels[k - 1].cloud.size());
    EXPECT_GE(l.voxel_m, 2.0 * levels[k - 1].voxel_m);
    // Every finest Gaussian and its stand-in share a voxel of this level.
    EXPECT_GT(l.geometric_error_m, levels[k - 1].geometric_error_m);
    EXPECT_LE(l.geometric_error_m, std::sqrt(3.0) * l.voxel_m);
  }
}

TEST(Lod, CoincidentOpaqueGaussiansSaturateAndSaySo) {
  GaussianCloud c = RandomCloud(50, 1);
  for (std::size_t i = 0; i < c.size(); ++i) {
    c.means[i] = {0.1f, 0.1f, 0.1f};
    c.opacity_logits[i] = 4.0f;  // 0.98 each: their sum cannot be one Gaussian's opacity
  }
  LodOptions o;
  o.min_gaussians = 1;
  const std::vector<LodLevel> levels = BuildLod(o, c);
  ASSERT_GE(levels.size(), 2u);
  EXPECT_EQ(levels[1].cloud.size(), 1u);
  EXPECT_EQ(levels[1].saturated, 1u);
  EXPECT_NEAR(1.0 / (1.0 + std::exp(-levels[1].cloud.opacity_logits[0])), 0.99, 1e-6);
}

TEST(Lod, LevelsAreHandedOnOneByOneAndWrittenAsTheyCome) {
  const GaussianCloud finest = RandomCloud(5000, 3);
  LodOptions o;
  o.max_levels = 4;
  const std::vector<LodLevel> whole = BuildLod(o, finest);
  ASSERT_GE(whole.size(), 3u);
  const fs::path dir = testing::ScratchDir("lod_writer");
  LodWriter writer(dir.string());
  int next = 0;
  BuildLodLevels(o, finest, [&](const LodLevel& level, const GaussianCloud& cloud) {
    EXPECT_EQ(level.level, next++);
    if (level.level == 0) EXPECT_EQ(&cloud, &finest);  // the finest level is not copied
    EXPECT_EQ(level.count, cloud.size());
    writer.Add(level, cloud);
  });
  writer.Finish();
  ASSERT_EQ(static_cast<std::size_t>(next), whole.size());
  const nlohmann::json doc = nlohmann::json::parse(ReadTextFile((dir / "lod.json").string()));
  ASSERT_EQ(doc["levels"].size(), whole.size());
  for (std::size_t k = 0; k < whole.size(); ++k) {
    SCOPED_TRACE("level " + std::to_string(k));
    EXPECT_EQ(doc["levels"][k]["count"], whole[k].cloud.size());
    EXPECT_EQ(doc["levels"][k]["geometric_error_m"], whole[k].geometric_error_m);
    EXPECT_TRUE(writer.levels()[k].cloud.size() == 0);  // figures only
    const GaussianCloud back = ReadGaussiansPly((dir / doc["levels"][k]["file"].get<std::string>()).string());
    ASSERT_EQ(back.size(), whole[k].cloud.size());
    EXPECT_EQ(back.means.back(), whole[k].cloud.means.back());
    EXPECT_EQ(back.sh.front(), whole[k].cloud.sh.front());
  }
}

TEST(Lod, OptionsAreChecked) {
  LodOptions o;
  o.base_voxel_m = 0;
  EXPECT_THROW(BuildLod(o, RandomCloud(10, 1)), Error);
}

}  // namespace
}  // namespace skyfall
