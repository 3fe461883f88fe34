#pragma once
/// Camera models with lens distortion: the colour camera as the sensor delivers its images.
///
/// Every model maps a point of the camera frame to a pixel in two steps,
///   ideal normalised x_n = (x / z, y / z)  --distort-->  distorted normalised x_d  --K-->  pixel,
/// so the distortion is a map of the normalised plane onto itself:
///   - kPinhole: x_d = x_n (no lens);
///   - kRadTan: OpenCV's radial-tangential model (k1, k2, p1, p2, k3), as ORB-SLAM3's "PinHole"
///     settings and OpenCV's calibrateCamera write it:
///       x_d = x_n (1 + k1 r^2 + k2 r^4 + k3 r^6) + [2 p1 x y + p2 (r^2 + 2 x^2), p1 (r^2 + 2 y^2) + 2 p2 x y];
///   - kRational: OpenCV's 8-coefficient rational model (k1..k6, p1, p2; the Azure Kinect's factory
///     calibration): the radial factor becomes (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6);
///   - kKannalaBrandt: the equidistant model (k1..k4, ORB-SLAM3's "KannalaBrandt8", OpenCV's fisheye),
///       theta = atan(r), theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
///       x_d = x_n theta_d / r.
/// The rest of the system works in the *ideal* pinhole image of the same K (PinholeCamera): keypoints
/// are undistorted once per frame (Undistorter's lookup), and images that are processed densely are
/// remapped onto that grid. Pixel coordinates as PinholeCamera: the centre of the top-left pixel is (0, 0).
#include <array>
#include <optional>
#include <string>

#include "ltlo/core/camera.h"
#include "ltlo/core/eigen_types.h"

namespace ltlo {

enum class LensModel { kPinhole, kRadTan, kRational, kKannalaBrandt };

/// "pinhole", "radtan", "rational", "kannala-brandt" (log lines and error messages).
const char* lensModelName(LensModel model);

/// Distortion of the normalised image plane. Coefficients not used by the model are zero.
struct LensDistortion {
  LensModel model = LensModel::kPinhole;
  double k1 = 0.0, k2 = 0.0, k3 = 0.0, k4 = 0.0, k5 = 0.0, k6 = 0.0;  ///< radial
  double p1 = 0.0, p2 = 0.0;                                          ///< tangential (radtan, rational)

  /// False for the pinhole model and for a model whose coefficients are all zero: then distort()
  /// and undistort() are the identity, and every stage takes the pinhole path unchanged.
  bool isDistorted() const;
  /// Ideal normalised point -> distorted normalised point, and its 2x2 Jacobian d x_d / d x_n.
  Vec2 distort(const Vec2& x_n) const;
  Mat2 distortJacobian(const Vec2& x_n) const;
  /// Inverse of distort() by Newton's method from x_d (to |residual| < 1e-12 in normalised units, at
  /// most 50 iterations); nullopt when it does not converge (a point outside the lens' valid field).
  std::optional<Vec2> undistort(const Vec2& x_d) const;
  /// "radtan k1=-0.05 k2=0.01 p1=0 p2=0 k3=0" (one log line).
  std::string describe() const;
};

/// A pinhole K with a lens: projection of camera-frame points to the pixels of the raw image.
class CameraModel {
 public:
  CameraModel() = default;
  CameraModel(const PinholeCamera& pinhole, const LensDistortion& lens) : pinhole_(pinhole), lens_(lens) {}

  /// The ideal camera of the same K and image size (what tracking, mapping and loop closing use).
  const PinholeCamera& pinhole() const { return pinhole_; }
  const LensDistortion& lens() const { return lens_; }
  bool isDistorted() const { return lens_.isDistorted(); }

  /// Camera-frame point (z > 0) -> raw image pixel, and its 2x3 Jacobian.
  Vec2 project(const Vec3& p_c) const;
  Mat23 projectJacobian(const Vec3& p_c) const;
  /// Raw pixel -> point at depth 1 on its ray (x_n, y_n, 1); nullopt outside the lens' field.
  std::optional<Vec3> unproject(const Vec2& u_raw) const;
  /// d(unproject)/d(u_raw), 3x2 (the last row is zero); asserts that unproject succeeds.
  Eigen::Matrix<double, 3, 2> unprojectJacobian(const Vec2& u_raw) const;
  /// Raw pixel <-> ideal (undistorted) pixel of pinhole().
  std::optional<Vec2> undistortPixel(const Vec2& u_raw) const;
  Vec2 distortPixel(const Vec2& u_ideal) const;

  /// The same lens on an image scaled by `factor` (pixel centres as PinholeCamera::scaled).
  CameraModel scaled(double factor) const { return CameraModel(pinhole_.scaled(factor), lens_); }

 private:
  PinholeCamera pinhole_;
  LensDistortion lens_;
};

}  // namespace ltlo
