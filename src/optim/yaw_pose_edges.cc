#include "ltlo/optim/yaw_pose_edges.h"

#include <cmath>

#include "ltlo/core/assert.h"

namespace ltlo::optim {

VertexYawPose::VertexYawPose(int id, const SE3& T_w_b, const Vec3& up_w) : BaseVertex(id, T_w_b) {
  const double norm = up_w.norm();
  LTLO_ASSERT(std::isfinite(norm) && norm > 0.0, "VertexYawPose: up axis " << up_w.transpose());
  up_w_ = up_w / norm;
}

SE3 VertexYawPose::plus(const SE3& T_w_b, const Delta& delta) const {
  const Quat turn = so3ExpQuat(up_w_ * delta(0));
  return SE3(normalizeQuat(turn * T_w_b.quaternion()), T_w_b.translation() + delta.tail<3>());
}

void EdgeYawRelativePose::computeError() {
  const SE3& T_w_i = estimate<0>();
  const SE3& T_w_j = estimate<1>();
  const Mat3 R_i_t = T_w_i.rotationMatrix().transpose();
  error_.head<3>() = so3Log(measurement_.rotationMatrix().transpose() * R_i_t * T_w_j.rotationMatrix());
  error_.tail<3>() = R_i_t * (T_w_j.translation() - T_w_i.translation()) - measurement_.translation();
}

void EdgeYawRelativePose::linearizeOplus() {
  const SE3& T_w_i = estimate<0>();
  const SE3& T_w_j = estimate<1>();
  const Vec3& up_w = vertexAs<0>()->up_w();
  const Mat3 R_i_t = T_w_i.rotationMatrix().transpose();
  const Mat3 R_j_t = T_w_j.rotationMatrix().transpose();
  const Vec3 e_R = so3Log(measurement_.rotationMatrix().transpose() * R_i_t * T_w_j.rotationMatrix());
  // A yaw of pose j is the right perturbation Exp(R_j^T up d_yaw); of pose i, its inverse.
  const Vec3 d_e_R_d_yaw_j = so3RightJacobianInverse(e_R) * (R_j_t * up_w);
  const Vec3 d_ij = T_w_j.translation() - T_w_i.translation();
  Eigen::Matrix<double, 6, 4>& J_i = jacobian<0>();
  Eigen::Matrix<double, 6, 4>& J_j = jacobian<1>();
  J_i.setZero();
  J_j.setZero();
  J_i.block<3, 1>(0, 0) = -d_e_R_d_yaw_j;
  J_i.block<3, 1>(3, 0) = R_i_t * hat(d_ij) * up_w;
  J_i.block<3, 3>(3, 1) = -R_i_t;
  J_j.block<3, 1>(0, 0) = d_e_R_d_yaw_j;
  J_j.block<3, 3>(3, 1) = R_i_t;
}

}  // namespace ltlo::optim
