#include "ltlo/optim/vertices.h"

#include "ltlo/imu/inertial_residual.h"

namespace ltlo::optim {

SE3 VertexPose::plus(const SE3& T_w_b, const Delta& delta) const {
  const Vec3 dphi = delta.head<3>();
  const Vec3 drho = delta.tail<3>();
  return SE3(normalizeQuat(T_w_b.quaternion() * so3ExpQuat(dphi)), T_w_b.translation() + T_w_b.quaternion() * drho);
}

Mat36 VertexPose::d_point_d_delta(const SE3& /*T_w_b*/, const Vec3& p_b) {
  Mat36 J;
  J.leftCols<3>() = hat(p_b);
  J.rightCols<3>() = -Mat3::Identity();
  return J;
}

Mat36 VertexCameraPose::d_point_d_delta(const SE3& /*T_c_w*/, const Vec3& p_c) {
  Mat36 J;
  J.leftCols<3>() = -hat(p_c);
  J.rightCols<3>() = Mat3::Identity();
  return J;
}

Mat3 VertexGravityDir::plus(const Mat3& R_w_g, const Delta& delta) const {
  return imu::updateGravityRotation(R_w_g, delta);
}

}  // namespace ltlo::optim
