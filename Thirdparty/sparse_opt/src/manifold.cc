#include "sparse_opt/manifold.h"

#include <cmath>

namespace sparse_opt {

namespace {
constexpr double kSmallAngle = 1e-8;
}  // namespace

Mat3 hat(const Vec3& a) {
  Mat3 m;
  m << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
  return m;
}

Quat so3Exp(const Vec3& phi) {
  const double theta = phi.norm();
  if (theta < kSmallAngle) {
    // First order; normalised so the result stays a rotation.
    return Quat(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z()).normalized();
  }
  const double half = 0.5 * theta;
  const Vec3 axis_sin = phi * (std::sin(half) / theta);
  return Quat(std::cos(half), axis_sin.x(), axis_sin.y(), axis_sin.z());
}

Vec3 so3Log(const Quat& q_in) {
  Quat q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // same rotation, angle in [0, pi]
  const Vec3 v = q.vec();
  const double sin_half = v.norm();
  if (sin_half < kSmallAngle) return 2.0 * v / q.w();
  const double theta = 2.0 * std::atan2(sin_half, q.w());
  return v * (theta / sin_half);
}

Mat3 so3RightJacobian(const Vec3& phi) {
  const double theta = phi.norm();
  const Mat3 phi_hat = hat(phi);
  if (theta < 1e-5) return Mat3::Identity() - 0.5 * phi_hat + phi_hat * phi_hat / 6.0;
  const double theta2 = theta * theta;
  return Mat3::Identity() - (1.0 - std::cos(theta)) / theta2 * phi_hat +
         (theta - std::sin(theta)) / (theta2 * theta) * phi_hat * phi_hat;
}

Mat3 so3RightJacobianInverse(const Vec3& phi) {
  const double theta = phi.norm();
  const Mat3 phi_hat = hat(phi);
  if (theta < 1e-5) return Mat3::Identity() + 0.5 * phi_hat + phi_hat * phi_hat / 12.0;
  const double theta2 = theta * theta;
  const double coeff = 1.0 / theta2 - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  return Mat3::Identity() + 0.5 * phi_hat + coeff * phi_hat * phi_hat;
}

Mat3 so3LeftJacobian(const Vec3& phi) { return so3RightJacobian(-phi); }

SE3 SE3::exp(const Vec6& xi) {
  const Vec3 phi = xi.head<3>();
  const Vec3 rho = xi.tail<3>();
  return SE3(so3Exp(phi), so3LeftJacobian(phi) * rho);
}

}  // namespace sparse_opt
