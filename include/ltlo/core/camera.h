#pragma once
/// Pinhole camera with registered depth (DATA_FORMAT.md: depth shares the colour camera's grid).
/// Pixel coordinates: u right, v down, the centre of the top-left pixel is (0, 0).
#include "ltlo/core/eigen_types.h"

namespace ltlo {

class PinholeCamera {
 public:
  PinholeCamera() = default;
  PinholeCamera(double fx, double fy, double cx, double cy, int width, int height)
      : fx_(fx), fy_(fy), cx_(cx), cy_(cy), width_(width), height_(height) {}

  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  int width() const { return width_; }
  int height() const { return height_; }
  Mat3 K() const {
    Mat3 k;
    k << fx_, 0.0, cx_, 0.0, fy_, cy_, 0.0, 0.0, 1.0;
    return k;
  }

  /// Projects a point in the camera frame (z > 0 expected) to pixel coordinates.
  Vec2 project(const Vec3& p_c) const {
    const double inv_z = 1.0 / p_c.z();
    return Vec2(fx_ * p_c.x() * inv_z + cx_, fy_ * p_c.y() * inv_z + cy_);
  }
  /// d(project)/d(p_c), 2x3.
  Mat23 projectJacobian(const Vec3& p_c) const {
    const double inv_z = 1.0 / p_c.z();
    const double inv_z2 = inv_z * inv_z;
    Mat23 J;
    J << fx_ * inv_z, 0.0, -fx_ * p_c.x() * inv_z2,  //
        0.0, fy_ * inv_z, -fy_ * p_c.y() * inv_z2;
    return J;
  }
  /// Back-projects pixel u with metric depth (z) to a point in the camera frame.
  Vec3 backProject(const Vec2& u, double depth_m) const {
    return Vec3((u.x() - cx_) / fx_ * depth_m, (u.y() - cy_) / fy_ * depth_m, depth_m);
  }
  /// d(backProject)/d[u, v, depth], 3x3.
  Mat3 backProjectJacobian(const Vec2& u, double depth_m) const {
    Mat3 J;
    J << depth_m / fx_, 0.0, (u.x() - cx_) / fx_,  //
        0.0, depth_m / fy_, (u.y() - cy_) / fy_,   //
        0.0, 0.0, 1.0;
    return J;
  }
  /// True when u lies inside the image with a margin of border_px pixels.
  bool isInImage(const Vec2& u, double border_px = 0.0) const {
    return u.x() >= border_px && u.y() >= border_px && u.x() <= width_ - 1 - border_px &&
           u.y() <= height_ - 1 - border_px;
  }
  /// Returns a camera for an image scaled by `factor` (e.g. 0.5 for the next pyramid level),
  /// keeping pixel centres consistent: u' = factor * (u + 0.5) - 0.5.
  PinholeCamera scaled(double factor) const {
    return PinholeCamera(fx_ * factor, fy_ * factor, (cx_ + 0.5) * factor - 0.5,
                         (cy_ + 0.5) * factor - 0.5, static_cast<int>(width_ * factor + 0.5),
                         static_cast<int>(height_ * factor + 0.5));
  }

 private:
  double fx_ = 1.0, fy_ = 1.0, cx_ = 0.0, cy_ = 0.0;
  int width_ = 0, height_ = 0;
};

}  // namespace ltlo
