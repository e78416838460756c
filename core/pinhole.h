// Pinhole camera in a local metric frame (the AOI's ENU frame).
// Pixel convention: the centre of the top-left pixel is (0, 0), as for the
// RPC model (COLMAP puts it at (0.5, 0.5); exports add the half pixel).
// Satellite cameras have focal lengths ~2e6 px and sit ~6e5 m away: double only.
#pragma once

#include <Eigen/Core>

namespace skyfall {

struct PinholeCamera {
  double fx = 1.0, fy = 1.0;  // focal lengths [px]
  double skew = 0.0;          // K(0,1) [px]
  double cx = 0.0, cy = 0.0;  // principal point [px]
  Eigen::Matrix3d cam_from_world_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d cam_from_world_translation = Eigen::Vector3d::Zero();  // x_cam = R X + t
  int width_px = 0;
  int height_px = 0;

  Eigen::Matrix3d K() const {
    Eigen::Matrix3d k;
    k << fx, skew, cx, 0, fy, cy, 0, 0, 1;
    return k;
  }
  Eigen::Vector3d Centre() const { return -cam_from_world_rotation.transpose() * cam_from_world_translation; }
  // Depth along the optical axis (positive in front of the camera).
  double Depth(const Eigen::Vector3d& world) const {
    return (cam_from_world_rotation * world + cam_from_world_translation).z();
  }
  Eigen::Vector2d Project(const Eigen::Vector3d& world) const {
    const Eigen::Vector3d c = cam_from_world_rotation * world + cam_from_world_translation;
    return {fx * c.x() / c.z() + skew * c.y() / c.z() + cx, fy * c.y() / c.z() + cy};
  }
};

}  // namespace skyfall
