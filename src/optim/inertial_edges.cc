#include "ltlo/optim/inertial_edges.h"

#include <Eigen/Cholesky>
#include <utility>

#include "ltlo/core/assert.h"

namespace ltlo::optim {

namespace {

// d r / d [dphi; drho] of a VertexPose from the residual's rotation and world-position Jacobians.
Eigen::Matrix<double, 9, 6> poseJacobian(const imu::Mat93& d_r_d_R, const imu::Mat93& d_r_d_p, const Mat3& R_w_b) {
  Eigen::Matrix<double, 9, 6> J;
  J.leftCols<3>() = d_r_d_R;
  J.rightCols<3>() = d_r_d_p * R_w_b;
  return J;
}

}  // namespace

Mat9 informationFromCovariance(const Mat9& covariance) {
  const Mat9 symmetric = 0.5 * (covariance + covariance.transpose());
  const Eigen::LLT<Mat9> llt(symmetric);
  LTLO_ASSERT(llt.info() == Eigen::Success, "informationFromCovariance: covariance is not positive definite");
  const Mat9 information = llt.solve(Mat9::Identity());
  return 0.5 * (information + information.transpose());
}

EdgeInertial::EdgeInertial(std::shared_ptr<const imu::Preintegrated> pim, const Vec3& g_w)
    : pim_(std::move(pim)), g_w_(g_w) {
  LTLO_ASSERT(pim_ != nullptr, "EdgeInertial: null preintegration");
  setInformation(informationFromCovariance(pim_->covariance()));
}

void EdgeInertial::computeError() {
  const imu::ImuBias bias{estimate<2>(), estimate<3>()};
  error_ = imu::inertialResidual(imu::navState(estimate<0>(), estimate<1>()), imu::navState(estimate<4>(), estimate<5>()),
                                 bias, *pim_, g_w_);
}

void EdgeInertial::linearizeOplus() {
  const imu::ImuBias bias{estimate<2>(), estimate<3>()};
  const imu::NavState state_i = imu::navState(estimate<0>(), estimate<1>());
  const imu::NavState state_j = imu::navState(estimate<4>(), estimate<5>());
  const imu::InertialResidualJacobians J = imu::inertialResidualJacobians(state_i, state_j, bias, *pim_, g_w_);
  jacobian<0>() = poseJacobian(J.d_r_d_R_i, J.d_r_d_p_i, state_i.R_w_b);
  jacobian<1>() = J.d_r_d_v_i;
  jacobian<2>() = J.d_r_d_b_g;
  jacobian<3>() = J.d_r_d_b_a;
  jacobian<4>() = poseJacobian(J.d_r_d_R_j, J.d_r_d_p_j, state_j.R_w_b);
  jacobian<5>() = J.d_r_d_v_j;
}

EdgeInertialGravity::EdgeInertialGravity(std::shared_ptr<const imu::Preintegrated> pim, double gravity_m_s2)
    : pim_(std::move(pim)), gravity_m_s2_(gravity_m_s2) {
  LTLO_ASSERT(pim_ != nullptr, "EdgeInertialGravity: null preintegration");
  setInformation(informationFromCovariance(pim_->covariance()));
}

void EdgeInertialGravity::computeError() {
  const imu::ImuBias bias{estimate<2>(), estimate<3>()};
  const Vec3 g_w = imu::gravityFromRotation(estimate<6>(), gravity_m_s2_);
  error_ = imu::inertialResidual(imu::navState(estimate<0>(), estimate<1>()), imu::navState(estimate<4>(), estimate<5>()),
                                 bias, *pim_, g_w);
}

void EdgeInertialGravity::linearizeOplus() {
  const imu::ImuBias bias{estimate<2>(), estimate<3>()};
  const imu::NavState state_i = imu::navState(estimate<0>(), estimate<1>());
  const imu::NavState state_j = imu::navState(estimate<4>(), estimate<5>());
  const Mat3& R_w_g = estimate<6>();
  const Vec3 g_w = imu::gravityFromRotation(R_w_g, gravity_m_s2_);
  const imu::InertialResidualJacobians J = imu::inertialResidualJacobians(state_i, state_j, bias, *pim_, g_w);
  jacobian<0>() = poseJacobian(J.d_r_d_R_i, J.d_r_d_p_i, state_i.R_w_b);
  jacobian<1>() = J.d_r_d_v_i;
  jacobian<2>() = J.d_r_d_b_g;
  jacobian<3>() = J.d_r_d_b_a;
  jacobian<4>() = poseJacobian(J.d_r_d_R_j, J.d_r_d_p_j, state_j.R_w_b);
  jacobian<5>() = J.d_r_d_v_j;
  jacobian<6>() = J.d_r_d_g_w * imu::gravityJacobian(R_w_g, gravity_m_s2_);
}

Mat6 biasWalkInformation(const imu::ImuNoise& noise, double interval_s, double lambda_imu) {
  LTLO_ASSERT(interval_s > 0.0, "biasWalkInformation: interval_s = " << interval_s << ", expected > 0");
  LTLO_ASSERT(lambda_imu >= 0.0, "biasWalkInformation: lambda_imu = " << lambda_imu << ", expected >= 0");
  const Mat6 covariance = noise.biasWalkCovariance(interval_s);
  const Mat6 information = covariance.ldlt().solve(Mat6::Identity());
  return lambda_imu * 0.5 * (information + information.transpose());
}

void EdgeStatePrior::computeError() {
  const SE3& T = estimate<0>();
  const Mat3 R_0_t = measurement_.T_w_b.rotationMatrix().transpose();
  error_.segment<3>(0) = so3Log(R_0_t * T.rotationMatrix());
  error_.segment<3>(3) = R_0_t * (T.translation() - measurement_.T_w_b.translation());
  error_.segment<3>(6) = estimate<1>() - measurement_.v_w_b;
  error_.segment<3>(9) = estimate<2>() - measurement_.bias.b_g;
  error_.segment<3>(12) = estimate<3>() - measurement_.bias.b_a;
}

void EdgeStatePrior::linearizeOplus() {
  const SE3& T = estimate<0>();
  const Mat3 R_0_t = measurement_.T_w_b.rotationMatrix().transpose();
  const Vec3 e_R = so3Log(R_0_t * T.rotationMatrix());
  jacobian<0>().setZero();
  jacobian<0>().block<3, 3>(0, 0) = so3RightJacobianInverse(e_R);
  jacobian<0>().block<3, 3>(3, 3) = R_0_t * T.rotationMatrix();
  jacobian<1>().setZero();
  jacobian<1>().block<3, 3>(6, 0).setIdentity();
  jacobian<2>().setZero();
  jacobian<2>().block<3, 3>(9, 0).setIdentity();
  jacobian<3>().setZero();
  jacobian<3>().block<3, 3>(12, 0).setIdentity();
}

void EdgeBiasWalk::computeError() {
  error_.head<3>() = estimate<2>() - estimate<0>();
  error_.tail<3>() = estimate<3>() - estimate<1>();
}

void EdgeBiasWalk::linearizeOplus() {
  jacobian<0>().setZero();
  jacobian<1>().setZero();
  jacobian<2>().setZero();
  jacobian<3>().setZero();
  jacobian<0>().topRows<3>() = -Mat3::Identity();
  jacobian<1>().bottomRows<3>() = -Mat3::Identity();
  jacobian<2>().topRows<3>() = Mat3::Identity();
  jacobian<3>().bottomRows<3>() = Mat3::Identity();
}

}  // namespace ltlo::optim
