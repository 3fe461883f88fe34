// Small manifold helpers used by the sparse_opt vertices and edges: SO3 / SE3 exponential and
// logarithm, hat operator and SO3 Jacobians. Twists are ordered [phi; rho] (rotation first).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace sparse_opt {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat3 = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Quat = Eigen::Quaterniond;

/// Skew-symmetric matrix with hat(a) * b = a x b.
Mat3 hat(const Vec3& a);

/// Rotation exp(hat(phi)) as a unit quaternion; phi in rad.
Quat so3Exp(const Vec3& phi);

/// Rotation vector of a unit quaternion, angle in [0, pi].
Vec3 so3Log(const Quat& q);

/// SO3 right Jacobian Jr(phi): Exp(phi + d) ~= Exp(phi) Exp(Jr(phi) d).
Mat3 so3RightJacobian(const Vec3& phi);

/// Inverse of the SO3 right Jacobian: Log(Exp(phi) Exp(d)) ~= phi + JrInv(phi) d.
Mat3 so3RightJacobianInverse(const Vec3& phi);

/// SO3 left Jacobian Jl(phi) = Jr(-phi).
Mat3 so3LeftJacobian(const Vec3& phi);

/// Rigid transform stored as unit quaternion + translation; T * p = R p + t.
class SE3 {
 public:
  SE3() : q_(Quat::Identity()), t_(Vec3::Zero()) {}
  SE3(const Quat& q, const Vec3& t) : q_(q.normalized()), t_(t) {}

  /// exp of the twist xi = [phi; rho]: R = Exp(phi), t = Jl(phi) rho.
  static SE3 exp(const Vec6& xi);

  const Quat& rotation() const { return q_; }
  Mat3 rotationMatrix() const { return q_.toRotationMatrix(); }
  const Vec3& translation() const { return t_; }

  SE3 inverse() const {
    const Quat q_inv = q_.conjugate();
    return SE3(q_inv, -(q_inv * t_));
  }
  SE3 operator*(const SE3& other) const { return SE3(q_ * other.q_, q_ * other.t_ + t_); }
  Vec3 operator*(const Vec3& p) const { return q_ * p + t_; }

 private:
  Quat q_;
  Vec3 t_;
};

}  // namespace sparse_opt
