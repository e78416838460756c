#include "sfm/features.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/format.h"

namespace skyfall {
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

cv::Mat DescriptorMat(const ImageFeatures& f) {
  return cv::Mat(static_cast<int>(f.keypoints.size()), 128, CV_32F,
                 const_cast<float*>(f.descriptors.data()));
}

// For each query descriptor, the train index that passes the ratio test, or -1.
std::vector<int> RatioMatches(const cv::Mat& query, const cv::Mat& train, double ratio) {
  std::vector<int> out(query.rows, -1);
  if (query.rows == 0 || train.rows < 2) return out;
  // Brute force rather than FLANN: FLANN's randomized trees draw from the
  // global rand(), so parallel matching would not be reproducible. Brute
  // force costs ~1.4x more on 4000 x 4000 SIFT descriptors.
  cv::BFMatcher matcher(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(query, train, knn, 2);
  for (const auto& m : knn) {
    if (m.size() == 2 && m[0].distance < ratio * m[1].distance) out[m[0].queryIdx] = m[0].trainIdx;
  }
  return out;
}

}  // namespace

void FeatureOptions::Check() const {
  auto need = [](bool ok, const char* field, double v) {
    if (!ok) throw Error("features", field, FormatDouble(v) + " is out of range");
  };
  need(max_features >= 16, "max_features", max_features);
  need(contrast_threshold > 0 && contrast_threshold < 1, "contrast_threshold", contrast_threshold);
  need(ratio > 0 && ratio < 1, "ratio", ratio);
  need(clahe_clip > 0, "clahe_clip", clahe_clip);
  need(stretch_low >= 0 && stretch_low < stretch_high && stretch_high <= 1, "stretch_high", stretch_high);
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
  const cv::Mat da = DescriptorMat(a), db = DescriptorMat(b);
  const std::vector<int> ab = RatioMatches(da, db, ratio);
  const std::vector<int> ba = RatioMatches(db, da, ratio);
  std::vector<std::pair<int, int>> out;
  for (int i = 0; i < static_cast<int>(ab.size()); ++i) {
    if (ab[i] >= 0 && ba[ab[i]] == i) out.emplace_back(i, ab[i]);
  }
  return out;
}

}  // namespace skyfall
