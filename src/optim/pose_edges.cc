#include "ltlo/optim/pose_edges.h"

namespace ltlo::optim {

void EdgePosePrior::computeError() {
  const SE3& T = estimate<0>();
  const Mat3 R_0_t = measurement_.rotationMatrix().transpose();
  error_.head<3>() = so3Log(R_0_t * T.rotationMatrix());
  error_.tail<3>() = R_0_t * (T.translation() - measurement_.translation());
}

void EdgePosePrior::linearizeOplus() {
  const SE3& T = estimate<0>();
  const Mat3 R_0_t = measurement_.rotationMatrix().transpose();
  const Vec3 e_R = so3Log(R_0_t * T.rotationMatrix());
  Eigen::Matrix<double, 6, 6>& J = jacobian<0>();
  J.setZero();
  J.topLeftCorner<3, 3>() = so3RightJacobianInverse(e_R);
  J.bottomRightCorner<3, 3>() = R_0_t * T.rotationMatrix();
}

void EdgeRelativePose::computeError() {
  const SE3 E = measurement_.inverse() * estimate<0>().inverse() * estimate<1>();
  error_.head<3>() = so3Log(E.quaternion());
  error_.tail<3>() = E.translation();
}

void EdgeRelativePose::linearizeOplus() {
  const SE3 T_i_j = estimate<0>().inverse() * estimate<1>();
  const Mat3 R_i_j = T_i_j.rotationMatrix();
  const Mat3 R_Z_t = measurement_.rotationMatrix().transpose();
  const SE3 E = measurement_.inverse() * T_i_j;
  const Mat3 Jr_inv = so3RightJacobianInverse(so3Log(E.quaternion()));
  Eigen::Matrix<double, 6, 6>& J_i = jacobian<0>();
  Eigen::Matrix<double, 6, 6>& J_j = jacobian<1>();
  J_i.setZero();
  J_j.setZero();
  J_i.topLeftCorner<3, 3>() = -Jr_inv * R_i_j.transpose();
  J_i.bottomLeftCorner<3, 3>() = R_Z_t * hat(T_i_j.translation());
  J_i.bottomRightCorner<3, 3>() = -R_Z_t;
  J_j.topLeftCorner<3, 3>() = Jr_inv;
  J_j.bottomRightCorner<3, 3>() = R_Z_t * R_i_j;
}

}  // namespace ltlo::optim
