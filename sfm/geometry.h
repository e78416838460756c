// Multi-view geometry for satellite pinhole cameras: rays, pairwise
// verification against the approximate cameras, tracks and triangulation.
#pragma once

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "core/height.h"
#include "core/option_range.h"
#include "core/pinhole.h"

namespace skyfall {

// Viewing ray of a pixel: origin (camera centre) and unit direction, world frame.
struct Ray {
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;
};
Ray PixelRay(const PinholeCamera& camera, const Eigen::Vector2d& pixel);

struct VerifyOptions {
  // Scene height range on the cameras' ENU up axis: a true match lies on the
  // epipolar segment between these heights. RunSfm converts the catalog's
  // ellipsoidal range (EnuUpAtOrigin).
  EnuUpM min_up;
  EnuUpM max_up;
  double min_threshold_px = 1.5;  // smallest accepted distance from the epipolar line [px]
  double mad_factor = 4.0;        // threshold = max(min, factor * 1.4826 * MAD)
  double segment_slack = 0.25;    // allowed overshoot beyond the height range, as a fraction
  // [m] added above and below the AOI's height range: crops also show what
  // stands around the AOI (a tower next to it), whose tie points are still good.
  double height_pad_m = 50.0;
};
// The verification's height range comes from each catalog, so only its
// tolerances are options.
template <class IO> void Visit(IO& io, VerifyOptions& o) {
  io.NotAnOption(o.min_up);  // the height range comes from each catalog
  io.NotAnOption(o.max_up);
  io("min_threshold_px", o.min_threshold_px,
     "Smallest accepted distance of a match from its epipolar line", range::Above(0));
  io("mad_factor", o.mad_factor,
     "The epipolar threshold is max(min_threshold_px, this x 1.4826 x the median absolute deviation of the pair's "
     "distances)", range::Above(0));
  io("segment_slack", o.segment_slack,
     "Overshoot allowed beyond the ends of the epipolar segment of the height range, as a fraction of its length",
     range::AtLeast(0));
  io("height_pad_m", o.height_pad_m,
     "Added above and below the AOI's height range, so that tie points on what stands around the AOI are kept",
     range::AtLeast(0));
}

// Keeps the matches whose point in `b` lies on the epipolar segment of its
// point in `a`. The cameras may be offset by a few pixels from each other
// (RPC pointing biases), so distances are measured from their median.
std::vector<std::pair<int, int>> VerifyMatches(const PinholeCamera& a, const PinholeCamera& b,
                                               const std::vector<Eigen::Vector2d>& keypoints_a,
                                               const std::vector<Eigen::Vector2d>& keypoints_b,
                                               const std::vector<std::pair<int, int>>& matches,
                                               const VerifyOptions& options);

// An observation: keypoint `keypoint` of image `image`.
struct Observation {
  int image = 0;
  int keypoint = 0;
  Eigen::Vector2d pixel;
};

// Union-find over pairwise matches. Tracks that see one image twice are dropped.
// `pair_matches[k]` holds the matches between images pairs[k].first and .second.
std::vector<std::vector<Observation>> BuildTracks(
    const std::vector<std::pair<int, int>>& pairs,
    const std::vector<std::vector<std::pair<int, int>>>& pair_matches,
    const std::vector<std::vector<Eigen::Vector2d>>& keypoints);

// Least-squares intersection of the observations' rays, refined by
// Gauss-Newton on the reprojection error. `cameras` indexed by image.
Eigen::Vector3d Triangulate(const std::vector<PinholeCamera>& cameras, const std::vector<Observation>& track);

// Largest angle between two rays of the track [deg].
double MaxTriangulationAngleDeg(const std::vector<PinholeCamera>& cameras, const std::vector<Observation>& track,
                                const Eigen::Vector3d& point);

}  // namespace skyfall
