// Tie points: SIFT on contrast-normalized images, ratio-test matching.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/option_range.h"

namespace skyfall {

struct FeatureOptions {
  int max_features = 4000;          // strongest SIFT keypoints kept per image
  double contrast_threshold = 0.02; // SIFT contrast threshold (OpenCV default 0.04; satellite crops are low contrast)
  double ratio = 0.8;               // Lowe's ratio test
  double clahe_clip = 2.0;          // CLAHE clip limit after the percentile stretch
  double stretch_low = 0.01;        // percentile mapped to 0 before CLAHE
  double stretch_high = 0.99;       // percentile mapped to 255
  void Check() const;               // throws Error("features", field, ...)
};
template <class IO> void Visit(IO& io, FeatureOptions& o) {
  io("max_features", o.max_features,
     "Strongest SIFT keypoints kept per image", range::AtLeast(16));
  io("contrast_threshold", o.contrast_threshold,
     "SIFT contrast threshold (OpenCV's default is 0.04; satellite crops are low in contrast)", range::Inside(0, 1));
  io("ratio", o.ratio,
     "Lowe's ratio test: a match is kept when its descriptor distance is below this fraction of the second best's",
     range::Inside(0, 1));
  io("clahe_clip", o.clahe_clip,
     "CLAHE clip limit, applied after the percentile stretch", range::Above(0));
  io("stretch_low", o.stretch_low,
     "Percentile, as a fraction, of the grey image mapped to 0 before CLAHE", range::In(0, 1));
  io("stretch_high", o.stretch_high,
     "Percentile, as a fraction, of the grey image mapped to 255 before CLAHE", range::In(0, 1));
}

struct ImageFeatures {
  std::vector<Eigen::Vector2d> keypoints;           // pixel centres at integers (RPC convention)
  std::vector<float> descriptors;                   // 128 per keypoint, row-major
  std::vector<std::array<std::uint8_t, 3>> colours; // RGB at each keypoint
};

// `pixels`: `bands` floats per pixel, row-major (any radiometric range;
// keypoint colours clamp to 0-255). `valid` (1 per pixel, optional) masks
// nodata: no keypoint lies in or near it.
ImageFeatures DetectFeatures(const std::vector<float>& pixels, int width_px, int height_px, int bands,
                             const FeatureOptions& options, const std::vector<std::uint8_t>* valid = nullptr);

// Matches (index in a, index in b) that pass the ratio test both ways.
std::vector<std::pair<int, int>> MatchFeatures(const ImageFeatures& a, const ImageFeatures& b, double ratio);

}  // namespace skyfall
