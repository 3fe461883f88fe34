#include "sparse_opt/types.h"

namespace sparse_opt {

void EdgeProjectPoint::computeError() {
  const Vec3 p_c = estimate<0>() * estimate<1>();
  const double inv_z = 1.0 / p_c.z();
  error_ << intrinsics_.fx * p_c.x() * inv_z + intrinsics_.cx - measurement_.x(),
      intrinsics_.fy * p_c.y() * inv_z + intrinsics_.cy - measurement_.y();
}

void EdgeProjectPoint::linearizeOplus() {
  const SE3& T_c_w = estimate<0>();
  const Vec3 p_c = T_c_w * estimate<1>();
  const double inv_z = 1.0 / p_c.z();
  Eigen::Matrix<double, 2, 3> d_uv_d_p_c;
  d_uv_d_p_c << intrinsics_.fx * inv_z, 0.0, -intrinsics_.fx * p_c.x() * inv_z * inv_z,  //
      0.0, intrinsics_.fy * inv_z, -intrinsics_.fy * p_c.y() * inv_z * inv_z;
  // Left update: p_c(delta) = exp(delta) p_c  =>  d p_c / d [phi; rho] = [-hat(p_c), I].
  jacobian<0>().leftCols<3>() = -d_uv_d_p_c * hat(p_c);
  jacobian<0>().rightCols<3>() = d_uv_d_p_c;
  jacobian<1>() = d_uv_d_p_c * T_c_w.rotationMatrix();
}

void EdgeSE3Relative::computeError() {
  const SE3 E = measurement_.inverse() * estimate<0>().inverse() * estimate<1>();
  error_.head<3>() = so3Log(E.rotation());
  error_.tail<3>() = E.translation();
}

void EdgeSE3Relative::linearizeOplus() {
  const SE3& T_w_i = estimate<0>();
  const SE3& T_w_j = estimate<1>();
  const SE3 E = measurement_.inverse() * T_w_i.inverse() * T_w_j;
  const Mat3 jr_inv = so3RightJacobianInverse(so3Log(E.rotation()));
  const Mat3 R_j_w = T_w_j.rotationMatrix().transpose();
  const Mat3 R_z_w = measurement_.rotationMatrix().transpose() * T_w_i.rotationMatrix().transpose();
  const Mat3 t_j_hat = hat(T_w_j.translation());
  // Derivation with left updates T <- exp([phi; rho]) T (world frame):
  //   R_E <- R_E Exp(-+R_j^T phi),  t_E <- t_E -+ R_Z^T R_i^T (rho - hat(t_j) phi).
  auto& J_i = jacobian<0>();
  auto& J_j = jacobian<1>();
  J_i.setZero();
  J_j.setZero();
  J_i.topLeftCorner<3, 3>() = -jr_inv * R_j_w;
  J_j.topLeftCorner<3, 3>() = jr_inv * R_j_w;
  J_i.bottomLeftCorner<3, 3>() = R_z_w * t_j_hat;
  J_j.bottomLeftCorner<3, 3>() = -R_z_w * t_j_hat;
  J_i.bottomRightCorner<3, 3>() = -R_z_w;
  J_j.bottomRightCorner<3, 3>() = R_z_w;
}

void EdgeSE3Prior::computeError() {
  const SE3& T = estimate<0>();
  error_.head<3>() = so3Log(measurement_.rotation().conjugate() * T.rotation());
  error_.tail<3>() = T.translation() - measurement_.translation();
}

void EdgeSE3Prior::linearizeOplus() {
  const SE3& T = estimate<0>();
  const Vec3 r = so3Log(measurement_.rotation().conjugate() * T.rotation());
  auto& J = jacobian<0>();
  J.setZero();
  J.topLeftCorner<3, 3>() = so3RightJacobianInverse(r) * T.rotationMatrix().transpose();
  J.bottomLeftCorner<3, 3>() = -hat(T.translation());
  J.bottomRightCorner<3, 3>() = Mat3::Identity();
}

}  // namespace sparse_opt
