// The SfM stage for satellite views: per image an RPC -> pinhole
// approximation in the AOI's ENU frame, SIFT tie points verified against
// those cameras, tracks, triangulation and a bundle adjustment of per-image
// offsets and points.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/option_range.h"
#include "core/pinhole.h"
#include "core/stage.h"
#include "sfm/bundle.h"
#include "sfm/features.h"
#include "sfm/geometry.h"
#include "sfm/rpc_to_pinhole.h"

namespace skyfall {

struct SfmOptions {
  PinholeFitOptions pinhole;
  FeatureOptions features;
  VerifyOptions verify;                      // heights are taken from the catalog
  BundleOptions bundle;
  int min_matches_per_pair = 20;             // verified matches for a pair to count
  int min_observations_per_image = 30;       // below this an image is left out
  double max_reprojection_before_ba_px = 50; // initial filter (RPC biases reach tens of px)
  double max_reprojection_after_ba_px = 2.0; // outlier cut between BA rounds
  double min_triangulation_angle_deg = 2.0;
  int ba_rounds = 2;
  // What fixes the absolute position, which tie points cannot see: empty, the
  // robust average of all images' RPCs; else the name of one image whose RPC
  // fixes the horizontal position (as s2p's reference image does; the height
  // stays the images' average). A tile without that image falls back to the
  // average and warns.
  std::string anchor_image;
  void Check() const;  // throws Error("sfm", field, ...)
};
template <class IO> void Visit(IO& io, SfmOptions& o) {
  io("pinhole", o.pinhole);
  io("features", o.features);
  io("verify", o.verify);
  io("bundle", o.bundle);
  io("min_matches_per_pair", o.min_matches_per_pair,
     "Verified matches an image pair needs to count", range::AtLeast(5));
  io("min_observations_per_image", o.min_observations_per_image,
     "An image with fewer tie-point observations is left out", range::AtLeast(3));
  io("max_reprojection_before_ba_px", o.max_reprojection_before_ba_px,
     "Points that reproject worse than this before bundle adjustment are dropped (RPC biases reach tens of pixels)",
     range::Above(0));
  io("max_reprojection_after_ba_px", o.max_reprojection_after_ba_px,
     "Outlier cut on the reprojection error between bundle adjustment rounds", range::Above(0));
  io("min_triangulation_angle_deg", o.min_triangulation_angle_deg,
     "Points triangulated from rays meeting at a smaller angle are dropped", range::FromBelow(0, 90));
  io("ba_rounds", o.ba_rounds,
     "Bundle adjustment rounds, with an outlier cut between them", range::AtLeast(1));
  io("anchor_image", o.anchor_image,
     "What fixes the absolute position: empty = the robust average of all images' RPCs; else the name of one image "
     "whose RPC fixes the horizontal position (a tile without it falls back to the average)");
}

struct ReprojectionStats {
  double median_px = 0, mean_px = 0, p90_px = 0;
  int count = 0;
};
ReprojectionStats ComputeStats(std::vector<double> errors_px);

struct SfmImage {
  std::string name;
  std::string path;
  std::string acquisition_time;
  std::optional<double> sun_elevation_deg;    // from the catalog, when the source states it
  std::optional<double> sun_azimuth_deg;      // clockwise from north
  Radiometry radiometry;                      // how its pixels are read (from the catalog)
  PinholeFit approximation;                   // RPC -> pinhole, before BA
  PinholeCamera camera;                       // final: the BA offset folded into cx, cy
  Eigen::Vector2d ba_offset_px = Eigen::Vector2d::Zero();
  int keypoints = 0;
  int observations = 0;
  bool used = false;
  std::string status;                         // "ok" or why it was left out
};

struct SfmPoint {
  Eigen::Vector3d enu_m;
  std::array<std::uint8_t, 3> rgb{};
  std::vector<Observation> track;
  double reprojection_error_px = 0;  // mean over the track after BA
};

struct PairStats {
  int a = 0, b = 0;    // image indices
  int ratio_matches = 0;
  int verified = 0;
};

struct SfmResult {
  std::vector<SfmImage> images;
  std::vector<PairStats> pairs;  // every image pair tried
  std::vector<SfmPoint> points;
  ReprojectionStats before, after;
  int verified_pairs = 0;
  std::string absolute_position;  // what fixed it, in words ("the average of 12 images' RPCs")
  StageReport report;
};

SfmResult RunSfm(const SfmOptions& options, const AoiCatalog& catalog, Progress& progress);

}  // namespace skyfall
