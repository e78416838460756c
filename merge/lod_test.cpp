#include "merge/lod.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <numeric>
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

// A roof-like surface: one small flat Gaussian per `spacing_m` cell of a
// square of `side_m` (corner at the origin), jittered inside its cell.
GaussianCloud SurfaceCloud(double side_m, double spacing_m, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> jitter(0.01f, static_cast<float>(spacing_m) - 0.01f), z(0.05f, 0.2f);
  const GaussianCloud shape = RandomCloud(1, seed);
  GaussianCloud c;
  const int cells = static_cast<int>(std::lround(side_m / spacing_m));
  for (int iy = 0; iy < cells; ++iy)
    for (int ix = 0; ix < cells; ++ix) {
      c.Append(shape, 0);
      c.means.back() = {static_cast<float>(ix * spacing_m) + jitter(rng),
                        static_cast<float>(iy * spacing_m) + jitter(rng), z(rng)};
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

// The levels of `finest` written to a scratch folder and read back.
struct Built {
  std::vector<LodLevel> levels;
  std::vector<GaussianCloud> clouds;
  fs::path dir;
};
Built BuildInScratch(const LodOptions& o, const GaussianCloud& finest, const std::string& name = "lod") {
  Built b;
  b.dir = testing::ScratchDir(name);
  b.levels = WriteLodLevels(o, [&](const GaussianChunkVisitor& visit) { visit(finest); }, b.dir.string());
  for (const LodLevel& l : b.levels)
    b.clouds.push_back(ReadGaussiansPly((b.dir / ("lod_" + std::to_string(l.level) + ".ply")).string()));
  return b;
}

// The pyramid as one global pass per level builds it (the definition the
// blocked build must reproduce): every level merged by voxel over the whole
// cloud, groups in sorted (voxel, index) order, a level kept when it
// reduces enough, the geometric error over every finest Gaussian's chain of
// stand-ins.
struct ReferenceLevel {
  double voxel_m = 0, geometric_error_m = 0;
  std::size_t saturated = 0;
  GaussianCloud cloud;
};
std::vector<ReferenceLevel> ReferencePyramid(const LodOptions& o, const GaussianCloud& finest) {
  std::vector<ReferenceLevel> levels(1);
  levels[0].cloud = finest;
  Eigen::Vector3f lo = finest.means[0], hi = lo;
  for (const auto& p : finest.means) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const double extent_m = (hi - lo).cast<double>().norm();
  std::vector<std::size_t> rep(finest.size());
  std::iota(rep.begin(), rep.end(), 0);
  double voxel_m = o.base_voxel_m;
  for (int k = 1; k <= o.max_levels; voxel_m *= 2) {
    const GaussianCloud& prev = levels.back().cloud;
    if (prev.size() <= o.min_gaussians || voxel_m > 2 * extent_m + o.base_voxel_m) break;
    std::vector<std::pair<std::array<std::int64_t, 3>, std::size_t>> keyed(prev.size());
    for (std::size_t i = 0; i < prev.size(); ++i) {
      for (int a = 0; a < 3; ++a) keyed[i].first[a] = static_cast<std::int64_t>(std::floor(prev.means[i][a] / voxel_m));
      keyed[i].second = i;
    }
    std::sort(keyed.begin(), keyed.end());
    ReferenceLevel level;
    level.voxel_m = voxel_m;
    std::vector<std::size_t> parent(prev.size());
    for (std::size_t a = 0; a < keyed.size();) {
      std::vector<std::size_t> members;
      std::size_t b = a;
      while (b < keyed.size() && keyed[b].first == keyed[a].first) members.push_back(keyed[b++].second);
      for (std::size_t i : members) parent[i] = level.cloud.size();
      level.saturated += !MergeGaussians(prev, members, &level.cloud);
      a = b;
    }
    if (static_cast<double>(level.cloud.size()) > o.min_reduction * prev.size()) continue;
    for (std::size_t i = 0; i < finest.size(); ++i) {
      rep[i] = parent[rep[i]];
      level.geometric_error_m =
          std::max(level.geometric_error_m, (finest.means[i] - level.cloud.means[rep[i]]).cast<double>().norm());
    }
    levels.push_back(std::move(level));
    ++k;
  }
  return levels;
}

// A cloud's Gaussians as sorted byte records: equal when the clouds hold
// the same Gaussians, bit for bit, in any order.
std::vector<std::string> SortedRecords(const GaussianCloud& c) {
  std::vector<std::string> records;
  for (std::size_t i = 0; i < c.size(); ++i) {
    GaussianCloud one;
    one.Append(c, i);
    records.push_back(GaussiansToPly(one).substr(GaussiansToPly(GaussianCloud()).size()));
  }
  std::sort(records.begin(), records.end());
  return records;
}

// Built block by block through a spill that writes every record to disk,
// on blocks much smaller than the scene (and than the coarse levels'
// voxels), the pyramid holds the very Gaussians of the global build.
TEST(Lod, BlockByBlockEqualsTheGlobalBuildBitForBit) {
  GaussianCloud finest = RandomCloud(20000, 11);
  for (std::size_t i = 0; i < 50; ++i) finest.means[i] = {2.0f, -4.0f, 0.25f};  // on block and voxel corners
  LodOptions o;
  o.base_voxel_m = 0.5;
  o.max_levels = 7;
  o.min_gaussians = 16;        // a deep pyramid from a small cloud
  o.block_m = 3;               // raised to 4 m: 16 x 16 blocks over the 64 m scene
  o.spill_buffer_mb = 1e-6;    // every record goes to disk at once
  const Built built = BuildInScratch(o, finest, "lod_blocks");
  const std::vector<ReferenceLevel> ref = ReferencePyramid(o, finest);
  ASSERT_EQ(built.levels.size(), ref.size());
  ASSERT_GE(ref.size(), 6u);
  EXPECT_GT(ref.back().voxel_m, 4.0);  // the coarse levels' voxels exceed the blocks
  for (std::size_t k = 0; k < ref.size(); ++k) {
    SCOPED_TRACE("level " + std::to_string(k));
    EXPECT_EQ(built.levels[k].voxel_m, ref[k].voxel_m);
    EXPECT_EQ(built.levels[k].count, ref[k].cloud.size());
    EXPECT_EQ(built.levels[k].saturated, ref[k].saturated);
    EXPECT_EQ(built.levels[k].geometric_error_m, ref[k].geometric_error_m);
    EXPECT_EQ(SortedRecords(built.clouds[k]), SortedRecords(ref[k].cloud));
  }
  EXPECT_FALSE(fs::exists(built.dir / ".lod_spill"));
  // The default blocks (one block for this scene) give the same Gaussians.
  LodOptions whole = o;
  whole.block_m = 128;
  whole.spill_buffer_mb = 64;
  const Built one = BuildInScratch(whole, finest, "lod_one_block");
  for (std::size_t k = 0; k < ref.size(); ++k) EXPECT_EQ(SortedRecords(one.clouds[k]), SortedRecords(built.clouds[k]));
}

TEST(Lod, EveryLevelPreservesMassAndMeanAndBoundsItsError) {
  const GaussianCloud finest = RandomCloud(20000, 7);
  LodOptions o;
  o.base_voxel_m = 0.5;  // too fine to merge anything: the first levels come from doubled voxels
  o.max_levels = 5;
  o.min_gaussians = 16;  // a deep pyramid from a small cloud
  const Built built = BuildInScratch(o, finest);
  const std::vector<LodLevel>& levels = built.levels;
  ASSERT_GE(levels.size(), 4u);
  const Moments ref = MomentsOf(finest);
  EXPECT_EQ(built.clouds[0].size(), finest.size());  // the finest level is the scene itself
  EXPECT_EQ(levels[0].geometric_error_m, 0.0);
  for (std::size_t k = 1; k < levels.size(); ++k) {
    const LodLevel& l = levels[k];
    SCOPED_TRACE("level " + std::to_string(k));
    EXPECT_EQ(l.saturated, 0u);
    EXPECT_EQ(l.count, built.clouds[k].size());
    const Moments got = MomentsOf(built.clouds[k]);
    EXPECT_NEAR(got.mass, ref.mass, kMassRelTol * ref.mass);
    EXPECT_NEAR((got.mean - ref.mean).norm(), 0.0, kMeanTolM);
    EXPECT_NEAR(got.sh0, ref.sh0, 1e-4);
    EXPECT_LT(l.count, levels[k - 1].count);
    EXPECT_LE(static_cast<double>(l.count), o.min_reduction * levels[k - 1].count);
    EXPECT_GE(l.voxel_m, 2.0 * levels[k - 1].voxel_m);
    // Every finest Gaussian and its stand-in share a voxel of this level.
    EXPECT_GT(l.geometric_error_m, levels[k - 1].geometric_error_m);
    EXPECT_LE(l.geometric_error_m, std::sqrt(3.0) * l.voxel_m);
  }
}

// The pyramid ends at a root of at most `min_gaussians`, whatever the
// city's area: four times the area gets one more level (its voxel twice
// as large), not a root four times as heavy. Every level of these surfaces
// keeps a quarter of its parent (four 0.5 m cells per 1 m voxel).
TEST(Lod, TheRootsSizeDoesNotGrowWithTheArea) {
  const LodOptions o;  // the defaults
  const Built small = BuildInScratch(o, SurfaceCloud(96, 0.5, 4), "lod_root_small");
  const Built large = BuildInScratch(o, SurfaceCloud(192, 0.5, 5), "lod_root_large");
  for (const Built* b : {&small, &large}) {
    ASSERT_GE(b->levels.size(), 2u);
    EXPECT_LE(b->levels.back().count, o.min_gaussians);
    EXPECT_GT(b->levels[b->levels.size() - 2].count, o.min_gaussians);  // no level past the first small enough
    for (std::size_t k = 1; k < b->levels.size(); ++k)
      EXPECT_EQ(b->levels[k].count * 4, b->levels[k - 1].count) << "level " << k;
  }
  EXPECT_EQ(large.levels.size(), small.levels.size() + 1);
  EXPECT_EQ(large.levels.back().voxel_m, 2 * small.levels.back().voxel_m);
  EXPECT_EQ(large.levels.back().count, small.levels.back().count);
}

TEST(Lod, CoincidentOpaqueGaussiansSaturateAndSaySo) {
  GaussianCloud c = RandomCloud(50, 1);
  for (std::size_t i = 0; i < c.size(); ++i) {
    c.means[i] = {0.1f, 0.1f, 0.1f};
    c.opacity_logits[i] = 4.0f;  // 0.98 each: their sum cannot be one Gaussian's opacity
  }
  LodOptions o;
  o.min_gaussians = 1;
  const Built built = BuildInScratch(o, c);
  ASSERT_GE(built.levels.size(), 2u);
  EXPECT_EQ(built.clouds[1].size(), 1u);
  EXPECT_EQ(built.levels[1].saturated, 1u);
  EXPECT_NEAR(1.0 / (1.0 + std::exp(-built.clouds[1].opacity_logits[0])), 0.99, 1e-6);
}

TEST(Lod, TheIndexListsEveryLevelFileWithItsFigures) {
  const GaussianCloud finest = RandomCloud(5000, 3);
  LodOptions o;
  o.max_levels = 4;
  o.min_gaussians = 16;
  const Built built = BuildInScratch(o, finest, "lod_index");
  ASSERT_GE(built.levels.size(), 3u);
  const nlohmann::json doc = nlohmann::json::parse(ReadTextFile((built.dir / "lod.json").string()));
  ASSERT_EQ(doc["levels"].size(), built.levels.size());
  for (std::size_t k = 0; k < built.levels.size(); ++k) {
    SCOPED_TRACE("level " + std::to_string(k));
    EXPECT_EQ(doc["levels"][k]["level"], k);
    EXPECT_EQ(doc["levels"][k]["count"], built.clouds[k].size());
    EXPECT_EQ(doc["levels"][k]["geometric_error_m"], built.levels[k].geometric_error_m);
    EXPECT_EQ(doc["levels"][k]["file"], "lod_" + std::to_string(k) + ".ply");
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
    for (const auto& p : built.clouds[k].means) lo = lo.cwiseMin(p.cast<double>()), hi = hi.cwiseMax(p.cast<double>());
    EXPECT_EQ(doc["levels"][k]["bounds_min_m"][0], lo.x());
    EXPECT_EQ(doc["levels"][k]["bounds_max_m"][2], hi.z());
  }
  // Level 0 is the finest cloud, in its order.
  EXPECT_EQ(ReadTextFile((built.dir / "lod_0.ply").string()), GaussiansToPly(finest));
}

TEST(Lod, OptionsAreChecked) {
  LodOptions o;
  o.base_voxel_m = 0;
  EXPECT_THROW(BuildInScratch(o, RandomCloud(10, 1)), Error);
  o = LodOptions();
  o.block_m = 0;
  EXPECT_THROW(BuildInScratch(o, RandomCloud(10, 1)), Error);
}

}  // namespace
}  // namespace skyfall
