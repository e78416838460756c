#include "sfm/features.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/format.h"
#include "core/simd.h"
#include "core/simd_target.h"

namespace skyfall {

// Matching's inner loops once per SIMD path (core/simd_target.h).
namespace match_baseline {
#define SKYFALL_MATCH_LANES 4
#include "sfm/match_kernels.inc"
#undef SKYFALL_MATCH_LANES
}  // namespace match_baseline
#if defined(__x86_64__)
SKYFALL_TARGET_BEGIN(SKYFALL_TARGET_AVX2)
namespace match_avx2 {
#define SKYFALL_MATCH_LANES 8
#include "sfm/match_kernels.inc"
#undef SKYFALL_MATCH_LANES
}  // namespace match_avx2
SKYFALL_TARGET_END
SKYFALL_TARGET_BEGIN(SKYFALL_TARGET_AVX512)
namespace match_avx512 {
#define SKYFALL_MATCH_LANES 16
#include "sfm/match_kernels.inc"
#undef SKYFALL_MATCH_LANES
}  // namespace match_avx512
SKYFALL_TARGET_END
#endif

namespace {

// Grey image stretched between two percentiles to 8 bits, then CLAHE, so that
// dark and hazy dates give comparable keypoints.
cv::Mat NormalizedGrey(const std::vector<float>& pixels, int width, int height, int bands,
                       const FeatureOptions& o) {
  std::vector<float> grey(static_cast<size_t>(width) * height);
  for (size_t p = 0; p < grey.size(); ++p) {
    float s = 0;
    for (int b = 0; b < std::min(bands, 3); ++b) s += pixels[p * bands + b];
    grey[p] = s / std::min(bands, 3);
  }
  std::vector<float> sorted = grey;
  const size_t lo_i = static_cast<size_t>(o.stretch_low * (sorted.size() - 1));
  const size_t hi_i = static_cast<size_t>(o.stretch_high * (sorted.size() - 1));
  std::nth_element(sorted.begin(), sorted.begin() + lo_i, sorted.end());
  const float lo = sorted[lo_i];
  std::nth_element(sorted.begin(), sorted.begin() + hi_i, sorted.end());
  const float hi = std::max(sorted[hi_i], lo + 1e-6f);
  cv::Mat out(height, width, CV_8U);
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c) {
      const float v = (grey[static_cast<size_t>(r) * width + c] - lo) / (hi - lo) * 255.0f;
      out.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(std::clamp(v, 0.0f, 255.0f));
    }
  cv::createCLAHE(o.clahe_clip, cv::Size(8, 8))->apply(out, out);
  return out;
}

struct MatchKernels {
  decltype(&match_baseline::BlockDistances) block_distances;
  decltype(&match_baseline::RowTop2) row_top2;
  decltype(&match_baseline::ColumnTop2) column_top2;
};

const MatchKernels& ActiveMatchKernels() {
  static const MatchKernels baseline{&match_baseline::BlockDistances, &match_baseline::RowTop2,
                                     &match_baseline::ColumnTop2};
#if defined(__x86_64__)
  static const MatchKernels avx2{&match_avx2::BlockDistances, &match_avx2::RowTop2, &match_avx2::ColumnTop2};
  static const MatchKernels avx512{&match_avx512::BlockDistances, &match_avx512::RowTop2, &match_avx512::ColumnTop2};
  return ForActivePath(baseline, avx2, avx512);
#else
  return baseline;
#endif
}

float SquaredNorm(const float* v) {
  float s = 0;
  for (int d = 0; d < match_baseline::kMatchDims; ++d) s += v[d] * v[d];
  return s;
}

// Descriptors in blocks of kMatchColumns, dimension-major within a block
// (BlockDistances' layout); padding columns are zero with an infinite norm,
// so no query is ever nearest to one.
struct PackedDescriptors {
  int count = 0, blocks = 0;
  std::vector<float> values, norm2;
};

PackedDescriptors Pack(const ImageFeatures& f) {
  using namespace match_baseline;
  PackedDescriptors p;
  p.count = static_cast<int>(f.keypoints.size());
  p.blocks = (p.count + kMatchColumns - 1) / kMatchColumns;
  const std::size_t columns = static_cast<std::size_t>(p.blocks) * kMatchColumns;
  p.values.assign(columns * kMatchDims, 0.0f);
  p.norm2.assign(columns, std::numeric_limits<float>::infinity());
  for (int c = 0; c < p.count; ++c) {
    const float* v = f.descriptors.data() + static_cast<std::size_t>(c) * kMatchDims;
    float* block = p.values.data() + static_cast<std::size_t>(c / kMatchColumns) * kMatchDims * kMatchColumns;
    for (int d = 0; d < kMatchDims; ++d) block[d * kMatchColumns + c % kMatchColumns] = v[d];
    p.norm2[c] = SquaredNorm(v);
  }
  return p;
}

// Nearest and second nearest (squared L2) in both directions from one pass
// over the distance matrix.
struct Nearest {
  std::vector<float> best, second;
  std::vector<int> index;
  explicit Nearest(std::size_t n)
      : best(n, std::numeric_limits<float>::infinity()), second(n, std::numeric_limits<float>::infinity()), index(n, -1) {}
  // The nearest index where it passes Lowe's ratio test (on distances, so
  // on squared distances with the squared ratio), else -1.
  std::vector<int> RatioPassed(int n, double ratio) const {
    std::vector<int> out(n, -1);
    const float ratio2 = static_cast<float>(ratio * ratio);
    for (int k = 0; k < n; ++k)
      if (index[k] >= 0 && best[k] < ratio2 * second[k]) out[k] = index[k];
    return out;
  }
};

void NearestBothWays(const ImageFeatures& a, const ImageFeatures& b, Nearest& a_to_b, Nearest& b_to_a) {
  using namespace match_baseline;
  const MatchKernels& kernels = ActiveMatchKernels();
  const PackedDescriptors train = Pack(b);
  const int na = static_cast<int>(a.keypoints.size());
  const int stride = train.blocks * kMatchColumns;
  std::vector<float> dist(static_cast<std::size_t>(kMatchRows) * stride);
  float query[kMatchRows * kMatchDims];
  float query_norm2[kMatchRows];
  for (int q0 = 0; q0 < na; q0 += kMatchRows) {
    for (int r = 0; r < kMatchRows; ++r) {
      const bool real = q0 + r < na;
      const float* v = real ? a.descriptors.data() + static_cast<std::size_t>(q0 + r) * kMatchDims : nullptr;
      for (int d = 0; d < kMatchDims; ++d) query[r * kMatchDims + d] = real ? v[d] : 0.0f;
      query_norm2[r] = real ? SquaredNorm(v) : std::numeric_limits<float>::infinity();
    }
    kernels.block_distances(query, query_norm2, train.values.data(), train.norm2.data(), train.blocks, dist.data());
    for (int r = 0; r < kMatchRows && q0 + r < na; ++r) {
      const float* row = dist.data() + static_cast<std::size_t>(r) * stride;
      kernels.row_top2(row, train.count, a_to_b.best[q0 + r], a_to_b.second[q0 + r], a_to_b.index[q0 + r]);
      kernels.column_top2(row, stride, q0 + r, b_to_a.best.data(), b_to_a.second.data(), b_to_a.index.data());
    }
  }
}

}  // namespace

void FeatureOptions::Check() const {
  CheckOptionRanges(*this, "features");
  if (!(stretch_low < stretch_high)) {
    throw Error("features", "stretch_high", FormatDouble(stretch_high) + " must be above stretch_low " +
                                                FormatDouble(stretch_low));
  }
}

ImageFeatures DetectFeatures(const std::vector<float>& pixels, int width, int height, int bands,
                             const FeatureOptions& o, const std::vector<std::uint8_t>* valid) {
  o.Check();
  if (width < 16 || height < 16 || bands < 1 || pixels.size() != static_cast<size_t>(width) * height * bands) {
    throw Error("features", "image", "needs at least 16x16 pixels and matching data");
  }
  const cv::Mat grey = NormalizedGrey(pixels, width, height, bands, o);
  auto sift = cv::SIFT::create(o.max_features, 3, o.contrast_threshold);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  cv::Mat mask;
  if (valid) {
    if (valid->size() != static_cast<size_t>(width) * height) throw Error("features", "valid", "mask size differs from the image");
    mask = cv::Mat(height, width, CV_8U, const_cast<std::uint8_t*>(valid->data())).clone() * 255;
    // A keypoint's support reaches ~8 px: none may see the edge of the fill.
    constexpr int kMaskMarginPx = 8;
    cv::erode(mask, mask, cv::Mat(), cv::Point(-1, -1), kMaskMarginPx);
  }
  sift->detectAndCompute(grey, valid ? cv::InputArray(mask) : cv::noArray(), keypoints, descriptors);
  ImageFeatures f;
  f.descriptors.assign(descriptors.ptr<float>(), descriptors.ptr<float>() + descriptors.total());
  for (const auto& k : keypoints) {
    f.keypoints.emplace_back(k.pt.x, k.pt.y);
    const int c = std::clamp(static_cast<int>(std::lround(k.pt.x)), 0, width - 1);
    const int r = std::clamp(static_cast<int>(std::lround(k.pt.y)), 0, height - 1);
    std::array<std::uint8_t, 3> rgb{};
    for (int b = 0; b < 3; ++b) {
      const float v = pixels[(static_cast<size_t>(r) * width + c) * bands + std::min(b, bands - 1)];
      rgb[b] = static_cast<std::uint8_t>(std::clamp(v, 0.0f, 255.0f));
    }
    f.colours.push_back(rgb);
  }
  return f;
}

std::vector<std::pair<int, int>> MatchFeatures(const ImageFeatures& a, const ImageFeatures& b, double ratio) {
  const int na = static_cast<int>(a.keypoints.size()), nb = static_cast<int>(b.keypoints.size());
  for (const ImageFeatures* f : {&a, &b})
    if (f->descriptors.size() != f->keypoints.size() * match_baseline::kMatchDims)
      throw Error("features", "descriptors", std::to_string(f->descriptors.size()) + " values for " +
                                                 std::to_string(f->keypoints.size()) + " keypoints (128 each)");
  std::vector<std::pair<int, int>> out;
  if (na < 2 || nb < 2) return out;  // no second nearest: no ratio test either way
  // Brute force (exact, and reproducible: FLANN's randomized trees draw
  // from the global rand()), as one pass over the distance matrix that
  // serves both directions.
  Nearest a_to_b(na), b_to_a(static_cast<std::size_t>((nb + match_baseline::kMatchColumns - 1) /
                                                      match_baseline::kMatchColumns) *
                                  match_baseline::kMatchColumns);
  NearestBothWays(a, b, a_to_b, b_to_a);
  const std::vector<int> ab = a_to_b.RatioPassed(na, ratio);
  const std::vector<int> ba = b_to_a.RatioPassed(nb, ratio);
  for (int i = 0; i < na; ++i) {
    if (ab[i] >= 0 && ba[ab[i]] == i) out.emplace_back(i, ab[i]);
  }
  return out;
}

}  // namespace skyfall
