#pragma once
/// sparse_opt vertices of the SLAM problems (namespace ltlo::optim).
///
/// Perturbation conventions (the Jacobians of every edge in optim/ follow them):
///   VertexPose        T_w_b (body/IMU pose in world), delta = [dphi; drho]:
///                       R_w_b <- R_w_b Exp(dphi)        (right perturbation, body frame)
///                       p_w_b <- p_w_b + R_w_b drho     (translation step in the body frame)
///                     This is the convention of imu/inertial_residual.h chained with
///                     dp = R_w_b drho, so the inertial Jacobians are used as they are.
///   VertexCameraPose  T_c_w (world to camera, vision-only problems), delta = [dphi; drho]:
///                       T_c_w <- SE3::exp(delta) T_c_w  (left perturbation, as sparse_opt's VertexSE3)
///   VertexPoint, VertexVelocity, VertexGyroBias, VertexAccBias   R^3, additive.
///   VertexGravityDir  R_w_g, delta = [d_x, d_y]: R_w_g <- R_w_g Exp([d_x, d_y, 0]) (yaw about
///                     gravity is unobservable and not updated), g_w = R_w_g (0, 0, -9.81).
/// Map points are created marginalised (Schur complement) by the builders.
#include <sparse_opt/vertex.h>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"

namespace ltlo::optim {

/// Body pose T_w_b, right-perturbed rotation and body-frame translation step (file comment).
class VertexPose final : public sparse_opt::BaseVertex<6, SE3> {
 public:
  explicit VertexPose(int id, const SE3& T_w_b = SE3()) : BaseVertex(id, T_w_b) {}
  SE3 plus(const SE3& T_w_b, const Delta& delta) const override;

  /// A world point in the body frame: p_b = T_w_b^-1 p_w.
  static Vec3 pointInFrame(const SE3& T_w_b, const Vec3& p_w) { return T_w_b.inverse() * p_w; }
  /// d p_b / d delta (3x6) at p_b = pointInFrame(T_w_b, p_w): [hat(p_b), -I].
  static Mat36 d_point_d_delta(const SE3& T_w_b, const Vec3& p_b);
  /// d p_b / d p_w = R_w_b^T.
  static Mat3 d_point_d_world(const SE3& T_w_b) { return T_w_b.rotationMatrix().transpose(); }
};

/// Camera pose T_c_w for vision-only problems, left perturbation (file comment).
class VertexCameraPose final : public sparse_opt::BaseVertex<6, SE3> {
 public:
  explicit VertexCameraPose(int id, const SE3& T_c_w = SE3()) : BaseVertex(id, T_c_w) {}
  SE3 plus(const SE3& T_c_w, const Delta& delta) const override { return SE3::exp(delta) * T_c_w; }

  /// p_c = T_c_w p_w.
  static Vec3 pointInFrame(const SE3& T_c_w, const Vec3& p_w) { return T_c_w * p_w; }
  /// d p_c / d delta (3x6) at p_c: [-hat(p_c), I].
  static Mat36 d_point_d_delta(const SE3& T_c_w, const Vec3& p_c);
  /// d p_c / d p_w = R_c_w.
  static Mat3 d_point_d_world(const SE3& T_c_w) { return T_c_w.rotationMatrix(); }
};

/// Additive R^3 vertex; Tag only makes the types distinct, so an edge cannot be wired to the
/// wrong kind of vector (a velocity where a bias is expected).
template <typename Tag>
class VertexVec3 final : public sparse_opt::BaseVertex<3, Vec3> {
 public:
  explicit VertexVec3(int id, const Vec3& x = Vec3::Zero()) : BaseVertex(id, x) {}
  Vec3 plus(const Vec3& x, const Delta& delta) const override { return x + delta; }
};
struct PointTag {};
struct VelocityTag {};
struct GyroBiasTag {};
struct AccBiasTag {};
/// Map point p_w (m).
using VertexPoint = VertexVec3<PointTag>;
/// Body velocity in world v_w_b (m/s).
using VertexVelocity = VertexVec3<VelocityTag>;
/// Gyroscope bias b_g (rad/s).
using VertexGyroBias = VertexVec3<GyroBiasTag>;
/// Accelerometer bias b_a (m/s^2).
using VertexAccBias = VertexVec3<AccBiasTag>;

/// Gravity direction R_w_g (2-DoF update, file comment).
class VertexGravityDir final : public sparse_opt::BaseVertex<2, Mat3> {
 public:
  explicit VertexGravityDir(int id, const Mat3& R_w_g = Mat3::Identity()) : BaseVertex(id, R_w_g) {}
  Mat3 plus(const Mat3& R_w_g, const Delta& delta) const override;
};

}  // namespace ltlo::optim
