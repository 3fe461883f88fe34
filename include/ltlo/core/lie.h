#pragma once
/// Lie-group helpers on Eigen: SO(3), SE(3) and Sim(3) (STYLE.md section 6: the only place where
/// exp/log, hat/vee, adjoints and Jacobians are written).
///
/// Conventions
/// - Rotation vectors phi (rad) map to SO(3) by exp(phi^) (Rodrigues).
/// - SE(3) twists are ordered xi = [phi; rho] (rotation first, then translation), as in g2o's
///   SE3Quat: exp(xi) = (Exp(phi), J_l(phi) rho).
/// - Left Jacobian J_l: exp(xi + d) ~= exp(J_l(xi) d) exp(xi);  right Jacobian J_r = J_l(-xi):
///   exp(xi + d) ~= exp(xi) exp(J_r(xi) d).
/// - Poses carry their frames in the name: T_a_b maps points from frame b into frame a.
#include "ltlo/core/eigen_types.h"

namespace ltlo {

/// Skew-symmetric matrix v^ with v^ w = v x w.
Mat3 hat(const Vec3& v);
/// Inverse of hat(): the vector of a skew-symmetric matrix (uses its antisymmetric part).
Vec3 vee(const Mat3& m);

/// SO(3) exponential of a rotation vector (rad), as a rotation matrix.
Mat3 so3Exp(const Vec3& phi);
/// SO(3) exponential as a unit quaternion with w >= 0.
Quat so3ExpQuat(const Vec3& phi);
/// SO(3) logarithm, |phi| in [0, pi]; stable near 0 and near pi.
Vec3 so3Log(const Mat3& R);
Vec3 so3Log(const Quat& q);

/// SO(3) right Jacobian J_r(phi) and its inverse; left ones are J_l(phi) = J_r(-phi).
Mat3 so3RightJacobian(const Vec3& phi);
Mat3 so3RightJacobianInverse(const Vec3& phi);
Mat3 so3LeftJacobian(const Vec3& phi);
Mat3 so3LeftJacobianInverse(const Vec3& phi);

/// Nearest rotation to a nearly orthonormal matrix (re-normalised through a quaternion).
Mat3 normalizeRotation(const Mat3& R);
/// Unit quaternion with non-negative w (the same rotation, a canonical sign).
Quat normalizeQuat(const Quat& q);

/// Rigid transform T_a_b = (R_a_b, t_a_b), stored as a unit quaternion and a translation.
class SE3 {
 public:
  SE3() : q_(Quat::Identity()), t_(Vec3::Zero()) {}
  SE3(const Quat& q, const Vec3& t) : q_(q.normalized()), t_(t) {}
  SE3(const Mat3& R, const Vec3& t) : q_(Quat(normalizeRotation(R))), t_(t) {}

  static SE3 identity() { return SE3(); }
  /// From a quaternion that is already unit, kept bit for bit (no re-normalisation, which may
  /// move the last bit): for readers of stored poses (the atlas file) that must round-trip exactly.
  static SE3 fromUnitQuaternion(const Quat& q_unit, const Vec3& t) {
    SE3 T;
    T.q_ = q_unit;
    T.t_ = t;
    return T;
  }
  /// From a homogeneous 4x4 matrix; the rotation block is re-orthonormalised.
  static SE3 fromMatrix(const Mat4& T);
  /// Exponential of a twist xi = [phi; rho].
  static SE3 exp(const Vec6& xi);
  /// Logarithm: the twist [phi; rho] with exp(log()) == *this.
  Vec6 log() const;

  const Quat& quaternion() const { return q_; }
  Mat3 rotationMatrix() const { return q_.toRotationMatrix(); }
  const Vec3& translation() const { return t_; }
  Vec3& translation() { return t_; }
  void setQuaternion(const Quat& q) { q_ = q.normalized(); }
  Mat4 matrix() const;
  /// Top 3x4 rows [R | t].
  Eigen::Matrix<double, 3, 4> matrix3x4() const;

  SE3 inverse() const;
  SE3 operator*(const SE3& other) const { return SE3(q_ * other.q_, q_ * other.t_ + t_); }
  SE3& operator*=(const SE3& other) { return *this = *this * other; }
  Vec3 operator*(const Vec3& p) const { return q_ * p + t_; }

  /// Adjoint Ad(T) on twists [phi; rho]: T exp(xi) T^-1 = exp(Ad(T) xi).
  Mat6 adjoint() const;

 private:
  Quat q_;
  Vec3 t_;
};

/// SE(3) left and right Jacobians (twists [phi; rho]) and their inverses.
Mat6 se3LeftJacobian(const Vec6& xi);
Mat6 se3LeftJacobianInverse(const Vec6& xi);
Mat6 se3RightJacobian(const Vec6& xi);
Mat6 se3RightJacobianInverse(const Vec6& xi);

/// Similarity S_a_b: p_a = s R p_b + t, for trajectory alignment (Umeyama with scale).
class Sim3 {
 public:
  Sim3() : q_(Quat::Identity()), t_(Vec3::Zero()), scale_(1.0) {}
  Sim3(const Quat& q, const Vec3& t, double scale) : q_(q.normalized()), t_(t), scale_(scale) {}
  explicit Sim3(const SE3& T) : q_(T.quaternion()), t_(T.translation()), scale_(1.0) {}

  const Quat& quaternion() const { return q_; }
  Mat3 rotationMatrix() const { return q_.toRotationMatrix(); }
  const Vec3& translation() const { return t_; }
  double scale() const { return scale_; }
  Mat4 matrix() const;

  Sim3 inverse() const;
  Sim3 operator*(const Sim3& o) const {
    return Sim3(q_ * o.q_, scale_ * (q_ * o.t_) + t_, scale_ * o.scale_);
  }
  Vec3 operator*(const Vec3& p) const { return scale_ * (q_ * p) + t_; }
  /// Applies the similarity to a pose: rotation composed, translation mapped (s R t + t_s).
  SE3 transformPose(const SE3& T) const { return SE3(q_ * T.quaternion(), *this * T.translation()); }

 private:
  Quat q_;
  Vec3 t_;
  double scale_;
};

}  // namespace ltlo
