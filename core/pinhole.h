// Pinhole camera in a local metric frame (the AOI's ENU frame).
// Pixel convention: the centre of the top-left pixel is (0, 0), as for the
// RPC model (COLMAP puts it at (0.5, 0.5); exports add the half pixel).
// Satellite cameras have focal lengths ~2e6 px and sit ~6e5 m away: double only.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>

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
  // [m] side of one pixel's footprint at `world` (depth over the geometric
  // mean focal length: the ground sample distance of a nadir view); +inf
  // behind the camera.
  double PixelFootprintM(const Eigen::Vector3d& world) const {
    const double depth_m = Depth(world);
    return depth_m > 0 ? depth_m / std::sqrt(fx * fy) : std::numeric_limits<double>::infinity();
  }
  Eigen::Vector2d Project(const Eigen::Vector3d& world) const {
    const Eigen::Vector3d c = cam_from_world_rotation * world + cam_from_world_translation;
    return {fx * c.x() / c.z() + skew * c.y() / c.z() + cx, fy * c.y() / c.z() + cy};
  }
};

// Back-projects pixels of a known depth along the optical axis to world
// points: X = R^T (K^-1 (x, y, 1) depth - t), with K^-1 and R^T computed once
// for the many pixels of one camera.
class PixelToWorld {
 public:
  explicit PixelToWorld(const PinholeCamera& cam)
      : K_inv_(cam.K().inverse()), R_t_(cam.cam_from_world_rotation.transpose()), t_(cam.cam_from_world_translation) {}
  Eigen::Vector3d operator()(double x_px, double y_px, double depth_m) const {
    return R_t_ * (K_inv_ * Eigen::Vector3d(x_px, y_px, 1.0) * depth_m - t_);
  }

 private:
  Eigen::Matrix3d K_inv_, R_t_;
  Eigen::Vector3d t_;
};

// A perspective camera at `eye` looking at `target` (ENU: z up), image rows
// pointing down the vertical through the target, `fov_deg` across the width,
// square pixels. The view direction must not be vertical.
inline PinholeCamera LookAtCamera(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, double fov_deg,
                                  int width_px, int height_px) {
  const Eigen::Vector3d forward = (target - eye).normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  PinholeCamera cam;
  cam.cam_from_world_rotation.row(0) = right.transpose();
  cam.cam_from_world_rotation.row(1) = down.transpose();
  cam.cam_from_world_rotation.row(2) = forward.transpose();
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * eye;
  cam.fx = cam.fy = 0.5 * width_px / std::tan(0.5 * fov_deg * M_PI / 180.0);
  cam.cx = 0.5 * (width_px - 1);
  cam.cy = 0.5 * (height_px - 1);
  cam.width_px = width_px;
  cam.height_px = height_px;
  return cam;
}

}  // namespace skyfall
