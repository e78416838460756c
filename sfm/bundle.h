// Bundle adjustment with Ceres for satellite views. The pinhole cameras from
// the RPCs are right up to a pointing bias, which over a crop of a few
// hundred metres is an image-space shift (the RPC bias-compensation model of
// Grodecki & Dial). So each image gets a 2D pixel offset, the points move
// freely, and a weak prior keeps the offsets near zero on average (the
// absolute position stays that of the RPCs).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/option_range.h"
#include "core/pinhole.h"
#include "sfm/geometry.h"

namespace skyfall {

struct BundleOptions {
  double huber_px = 1.0;              // robust loss scale [px]
  double offset_prior_sigma_px = 10;  // prior on each image offset [px]
  int max_iterations = 100;
  void Check() const;
};
template <class IO> void Visit(IO& io, BundleOptions& o) {
  io("huber_px", o.huber_px,
     "Scale of the Huber robust loss on reprojection errors", range::Above(0));
  io("offset_prior_sigma_px", o.offset_prior_sigma_px,
     "Standard deviation of the prior that keeps each image's offset near zero", range::Above(0));
  io("max_iterations", o.max_iterations,
     "Most solver iterations per bundle adjustment round", range::AtLeast(1));
}

struct BundleProblem {
  std::vector<PinholeCamera> cameras;       // held fixed
  std::vector<Eigen::Vector2d> offsets_px;  // refined: added to every projection of the image
  std::vector<Eigen::Vector3d> points;      // refined, one per track
  std::vector<std::vector<Observation>> tracks;
  std::vector<bool> image_used;             // images left out keep offset 0 and are ignored
  // The image whose RPC fixes the horizontal position (its offset held at 0;
  // the height along its line of sight stays the priors' average), or -1:
  // the robust average of all images' RPCs (the prior) fixes it.
  int anchor_image = -1;
  // The images whose offsets carry the prior, so that their RPCs' average
  // fixes the frame (AoiCatalog::gauge_acquisitions); empty: every image.
  std::vector<bool> gauge_image;
};

struct BundleSummary {
  int iterations = 0;
  double initial_cost = 0;
  double final_cost = 0;
  bool converged = false;
};

BundleSummary RunBundleAdjustment(BundleProblem* problem, const BundleOptions& options);

// Tie points cannot see a shift v of the whole scene that moves every image
// by its projection's Jacobian P_i v: only the offsets' prior fixes it, and
// the solver moves along that direction slowly (the tie points' cost is flat
// there), stopping short of the prior's minimum by a different amount in
// each tile. With gauge images (BundleProblem::gauge_image) this moves the
// solution along it to where the gauge images' offsets o_i satisfy
// sum P_i^T o_i = 0, the least-squares average of their RPCs, exactly:
// points X - v, every offset o_i + P_i v. Returns |v| [m]; 0 without gauge
// images or points.
double MoveToGaugeAverage(BundleProblem* bp);

// Reprojection error of every observation [px], in track order.
std::vector<double> ReprojectionErrors(const BundleProblem& problem);

}  // namespace skyfall
