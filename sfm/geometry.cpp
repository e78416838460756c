#include "sfm/geometry.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/stats.h"

namespace skyfall {
namespace {

// Where the ray crosses the plane at ENU up `up` (the cameras' frame).
Eigen::Vector3d AtUp(const Ray& ray, EnuUpM up) {
  return ray.origin + ((up.value - ray.origin.z()) / ray.direction.z()) * ray.direction;
}

int Find(std::vector<int>& parent, int x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

}  // namespace

Ray PixelRay(const PinholeCamera& camera, const Eigen::Vector2d& pixel) {
  // K^-1 for an upper-triangular K with skew.
  const double yn = (pixel.y() - camera.cy) / camera.fy;
  const double xn = (pixel.x() - camera.cx - camera.skew * yn) / camera.fx;
  const Eigen::Vector3d d = camera.cam_from_world_rotation.transpose() * Eigen::Vector3d(xn, yn, 1.0);
  return {camera.Centre(), d.normalized()};
}

std::vector<std::pair<int, int>> VerifyMatches(const PinholeCamera& a, const PinholeCamera& b,
                                               const std::vector<Eigen::Vector2d>& keypoints_a,
                                               const std::vector<Eigen::Vector2d>& keypoints_b,
                                               const std::vector<std::pair<int, int>>& matches,
                                               const VerifyOptions& o) {
  std::vector<double> distance(matches.size()), along(matches.size());
  for (size_t m = 0; m < matches.size(); ++m) {
    const Ray ray = PixelRay(a, keypoints_a[matches[m].first]);
    const Eigen::Vector2d p0 = b.Project(AtUp(ray, EnuUpM(o.min_up.value - o.height_pad_m)));
    const Eigen::Vector2d p1 = b.Project(AtUp(ray, EnuUpM(o.max_up.value + o.height_pad_m)));
    Eigen::Vector2d seg = p1 - p0;
    const double len = seg.norm();
    const Eigen::Vector2d q = keypoints_b[matches[m].second] - p0;
    if (len < 1e-9) {  // no parallax: the segment is a point
      distance[m] = q.norm();
      along[m] = 0.5;
      continue;
    }
    seg /= len;
    distance[m] = seg.x() * q.y() - seg.y() * q.x();  // signed perpendicular distance
    along[m] = q.dot(seg) / len;
  }
  const double med = Median(distance);
  std::vector<double> dev(distance.size());
  for (size_t m = 0; m < distance.size(); ++m) dev[m] = std::abs(distance[m] - med);
  const double threshold = std::max(o.min_threshold_px, o.mad_factor * 1.4826 * Median(dev));
  std::vector<std::pair<int, int>> out;
  for (size_t m = 0; m < matches.size(); ++m) {
    if (dev[m] <= threshold && along[m] >= -o.segment_slack && along[m] <= 1.0 + o.segment_slack) {
      out.push_back(matches[m]);
    }
  }
  return out;
}

std::vector<std::vector<Observation>> BuildTracks(
    const std::vector<std::pair<int, int>>& pairs,
    const std::vector<std::vector<std::pair<int, int>>>& pair_matches,
    const std::vector<std::vector<Eigen::Vector2d>>& keypoints) {
  std::vector<int> offset(keypoints.size() + 1, 0);
  for (size_t i = 0; i < keypoints.size(); ++i) offset[i + 1] = offset[i] + static_cast<int>(keypoints[i].size());
  std::vector<int> parent(offset.back());
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<bool> used(parent.size(), false);
  for (size_t p = 0; p < pairs.size(); ++p) {
    for (const auto& [ka, kb] : pair_matches[p]) {
      const int na = offset[pairs[p].first] + ka, nb = offset[pairs[p].second] + kb;
      used[na] = used[nb] = true;
      parent[Find(parent, na)] = Find(parent, nb);
    }
  }
  std::vector<std::vector<Observation>> groups(parent.size());
  for (int image = 0; image < static_cast<int>(keypoints.size()); ++image) {
    for (int k = 0; k < static_cast<int>(keypoints[image].size()); ++k) {
      const int node = offset[image] + k;
      if (used[node]) groups[Find(parent, node)].push_back({image, k, keypoints[image][k]});
    }
  }
  std::vector<std::vector<Observation>> tracks;
  for (auto& g : groups) {
    if (g.size() < 2) continue;
    bool repeated = false;
    for (size_t i = 1; i < g.size(); ++i) repeated = repeated || g[i].image == g[i - 1].image;
    if (!repeated) tracks.push_back(std::move(g));  // observations are sorted by image
  }
  return tracks;
}

Eigen::Vector3d Triangulate(const std::vector<PinholeCamera>& cameras, const std::vector<Observation>& track) {
  // Closest point to all rays: sum (I - d d^T) (X - C) = 0.
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const auto& o : track) {
    const Ray ray = PixelRay(cameras[o.image], o.pixel);
    const Eigen::Matrix3d proj = Eigen::Matrix3d::Identity() - ray.direction * ray.direction.transpose();
    A += proj;
    b += proj * ray.origin;
  }
  Eigen::Vector3d X = A.ldlt().solve(b);
  // Gauss-Newton on the pixel residuals; numerical Jacobian with a 1 mm step
  // is exact enough for a 3-parameter problem.
  for (int it = 0; it < 5; ++it) {
    Eigen::VectorXd r(2 * track.size());
    Eigen::MatrixXd J(2 * track.size(), 3);
    for (size_t i = 0; i < track.size(); ++i) {
      const PinholeCamera& cam = cameras[track[i].image];
      r.segment<2>(2 * i) = cam.Project(X) - track[i].pixel;
      for (int d = 0; d < 3; ++d) {
        Eigen::Vector3d h = Eigen::Vector3d::Zero();
        h[d] = 1e-3;
        J.block<2, 1>(2 * i, d) = (cam.Project(X + h) - cam.Project(X - h)) / 2e-3;
      }
    }
    const Eigen::Vector3d step = (J.transpose() * J).ldlt().solve(-J.transpose() * r);
    X += step;
    if (step.norm() < 1e-6) break;
  }
  return X;
}

double MaxTriangulationAngleDeg(const std::vector<PinholeCamera>& cameras, const std::vector<Observation>& track,
                                const Eigen::Vector3d& point) {
  double best = 0;
  for (size_t i = 0; i < track.size(); ++i) {
    const Eigen::Vector3d a = (cameras[track[i].image].Centre() - point).normalized();
    for (size_t j = i + 1; j < track.size(); ++j) {
      const Eigen::Vector3d b = (cameras[track[j].image].Centre() - point).normalized();
      best = std::max(best, std::acos(std::clamp(a.dot(b), -1.0, 1.0)));
    }
  }
  return best * 180.0 / M_PI;
}

}  // namespace skyfall
