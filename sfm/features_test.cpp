#include "sfm/features.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <random>

#include "core/error.h"
#include "core/simd.h"

namespace skyfall {
namespace {

// `n` random SIFT-like descriptors (128 values in 0-100); the first
// `planted` of `copy_from` (when given) are copied with a little noise, so
// they have a true match there.
ImageFeatures RandomFeatures(int n, std::uint32_t seed, const ImageFeatures* copy_from = nullptr, int planted = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> value(0.0f, 100.0f), noise(-4.0f, 4.0f);
  ImageFeatures f;
  for (int k = 0; k < n; ++k) {
    f.keypoints.emplace_back(k, k);
    for (int d = 0; d < 128; ++d) {
      const float v = copy_from && k < planted ? copy_from->descriptors[static_cast<std::size_t>(k) * 128 + d] + noise(rng)
                                               : value(rng);
      f.descriptors.push_back(v);
    }
  }
  return f;
}

// What OpenCV's brute-force matcher finds: the ratio test both ways on L2
// distances, kept where the two directions agree.
std::vector<std::pair<int, int>> OpenCvMatches(const ImageFeatures& a, const ImageFeatures& b, double ratio) {
  auto mat = [](const ImageFeatures& f) {
    return cv::Mat(static_cast<int>(f.keypoints.size()), 128, CV_32F, const_cast<float*>(f.descriptors.data()));
  };
  auto one_way = [&](const cv::Mat& q, const cv::Mat& t) {
    std::vector<std::vector<cv::DMatch>> knn;
    cv::BFMatcher(cv::NORM_L2).knnMatch(q, t, knn, 2);
    std::vector<int> out(q.rows, -1);
    for (const auto& m : knn)
      if (m.size() == 2 && m[0].distance < ratio * m[1].distance) out[m[0].queryIdx] = m[0].trainIdx;
    return out;
  };
  const std::vector<int> ab = one_way(mat(a), mat(b)), ba = one_way(mat(b), mat(a));
  std::vector<std::pair<int, int>> out;
  for (int i = 0; i < static_cast<int>(ab.size()); ++i)
    if (ab[i] >= 0 && ba[ab[i]] == i) out.emplace_back(i, ab[i]);
  return out;
}

TEST(Features, MatchingFindsWhatOpenCvBruteForceFinds) {
  // 700 x 901 descriptors (neither a multiple of the 16-wide blocks), 300
  // of them with a true match. Random descriptors keep every ratio far
  // from a tie, so float rounding (and fused multiply-adds on the wider
  // paths) cannot flip a decision: the sets must be equal on every path.
  const ImageFeatures a = RandomFeatures(700, 1);
  const ImageFeatures b = RandomFeatures(901, 2, &a, 300);
  const std::vector<std::pair<int, int>> reference = OpenCvMatches(a, b, 0.8);
  ASSERT_GE(reference.size(), 290u);  // the planted matches are found
  const SimdPath active = ActiveSimdPath();
  for (SimdPath path : SupportedSimdPaths()) {
    SetSimdPath(path);
    EXPECT_EQ(MatchFeatures(a, b, 0.8), reference) << SimdPathName(path);
    // Both directions are read from one distance matrix: swapping the
    // images must give the same pairs, swapped.
    std::vector<std::pair<int, int>> swapped;
    for (const auto& [i, j] : MatchFeatures(b, a, 0.8)) swapped.emplace_back(j, i);
    std::sort(swapped.begin(), swapped.end());
    EXPECT_EQ(swapped, reference) << SimdPathName(path);
  }
  SetSimdPath(active);
}

TEST(Features, MatchingNeedsTwoDescriptorsEachSideAndWholeDescriptors) {
  const ImageFeatures a = RandomFeatures(5, 3);
  EXPECT_TRUE(MatchFeatures(a, RandomFeatures(1, 4), 0.8).empty());
  EXPECT_TRUE(MatchFeatures(RandomFeatures(0, 5), a, 0.8).empty());
  // A descriptor copied exactly is its own nearest both ways, at distance 0.
  const ImageFeatures copy = a;
  EXPECT_EQ(MatchFeatures(a, copy, 0.8).size(), 5u);
  ImageFeatures broken = a;
  broken.descriptors.pop_back();
  try {
    MatchFeatures(a, broken, 0.8);
    FAIL() << "a short descriptor buffer was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("descriptors"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace skyfall
