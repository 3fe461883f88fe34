#include "ltlo/imu/inertial_residual.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/analytic_trajectory.h"
#include "ltlo/core/lie.h"
#include "numeric_jacobian.h"

namespace ltlo::imu {
namespace {

using test::AnalyticTrajectory;
using test::numericJacobian;

constexpr double kRateHz = 200.0;

ImuNoise testNoise() {
  ImuCalib calib;
  calib.rate_hz = kRateHz;
  return ImuNoise::fromCalib(calib);
}

/// Max |analytic - numeric| relative to max(1, |numeric|).
double jacobianError(const Mat93& analytic, const Mat93& numeric) {
  return (analytic - numeric).cwiseAbs().maxCoeff() / std::max(1.0, numeric.cwiseAbs().maxCoeff());
}

class ImuInertialResidualTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const AnalyticTrajectory traj;
    linearisation_bias_ = ImuBias{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
    pim_ = std::make_unique<Preintegrated>(linearisation_bias_, testNoise());
    pim_->integrate(samplesInInterval(traj.samples(0.0, 2.0, kRateHz, linearisation_bias_), 0.3, 1.1));
    state_i_ = traj.state(0.3);
    state_j_ = traj.state(1.1);
  }
  ImuBias linearisation_bias_;
  std::unique_ptr<Preintegrated> pim_;
  NavState state_i_, state_j_;
};

TEST_F(ImuInertialResidualTest, GroundTruthStatesGiveNearZeroResidual) {
  const Vec9 r = inertialResidual(state_i_, state_j_, linearisation_bias_, *pim_, gravityWorld());
  EXPECT_LT(r.head<3>().norm(), 1e-6);  // rad
  EXPECT_LT(r.segment<3>(3).norm(), 1e-5);  // m/s
  EXPECT_LT(r.tail<3>().norm(), 1e-5);  // m
  // predict() and the residual agree: the predicted state has a zero residual.
  const NavState predicted = predict(state_i_, *pim_, linearisation_bias_, gravityWorld());
  EXPECT_LT(inertialResidual(state_i_, predicted, linearisation_bias_, *pim_, gravityWorld()).norm(),
            1e-12);
}

// Every Jacobian against central differences, at states away from the solution (residual rotation
// ~0.2 rad so J_r^-1 matters) and a bias away from the linearisation bias (correction active).
TEST_F(ImuInertialResidualTest, JacobiansMatchNumericDifferentiation) {
  NavState s_i = state_i_;
  NavState s_j = state_j_;
  s_i.R_w_b = s_i.R_w_b * so3Exp(Vec3(0.05, -0.1, 0.08));
  s_j.R_w_b = s_j.R_w_b * so3Exp(Vec3(-0.07, 0.02, 0.12));
  s_i.p_w_b += Vec3(0.1, -0.2, 0.05);
  s_j.p_w_b += Vec3(-0.05, 0.1, 0.2);
  s_i.v_w_b += Vec3(0.3, 0.1, -0.2);
  s_j.v_w_b += Vec3(-0.1, 0.2, 0.1);
  ImuBias bias = linearisation_bias_;
  bias.b_g += Vec3(0.02, -0.03, 0.01);
  bias.b_a += Vec3(-0.1, 0.2, 0.05);
  const Vec3 g_w = gravityWorld();

  const InertialResidualJacobians J = inertialResidualJacobians(s_i, s_j, bias, *pim_, g_w);
  EXPECT_LT((J.residual - inertialResidual(s_i, s_j, bias, *pim_, g_w)).norm(), 1e-15);
  EXPECT_GT(J.residual.head<3>().norm(), 0.1);

  auto residual_with = [&](auto perturb) {
    return [&, perturb](const Vec3& d) {
      NavState a = s_i, b = s_j;
      ImuBias bb = bias;
      perturb(a, b, bb, d);
      return Vec9(inertialResidual(a, b, bb, *pim_, g_w));
    };
  };
  const double tol = 1e-7;
  EXPECT_LT(jacobianError(J.d_r_d_R_i, numericJacobian<9, 3>(residual_with(
                                           [](NavState& a, NavState&, ImuBias&, const Vec3& d) {
                                             a.R_w_b = a.R_w_b * so3Exp(d);
                                           }))),
            tol);
  EXPECT_LT(jacobianError(J.d_r_d_p_i, numericJacobian<9, 3>(residual_with(
                                           [](NavState& a, NavState&, ImuBias&, const Vec3& d) {
                                             a.p_w_b += d;
                                           }))),
            tol);
  EXPECT_LT(jacobianError(J.d_r_d_v_i, numericJacobian<9, 3>(residual_with(
                                           [](NavState& a, NavState&, ImuBias&, const Vec3& d) {
                                             a.v_w_b += d;
                                           }))),
            tol);
  EXPECT_LT(jacobianError(J.d_r_d_R_j, numericJacobian<9, 3>(residual_with(
                                           [](NavState&, NavState& b, ImuBias&, const Vec3& d) {
                                             b.R_w_b = b.R_w_b * so3Exp(d);
                                           }))),
            tol);
  EXPECT_LT(jacobianError(J.d_r_d_p_j, numericJacobian<9, 3>(residual_with(
                                           [](NavState&, NavState& b, ImuBias&, const Vec3& d) {
                                             b.p_w_b += d;
                                           }))),
            tol);
  EXPECT_LT(jacobianError(J.d_r_d_v_j, numericJacobian<9, 3>(residual_with(
                                           [](NavState&, NavState& b, ImuBias&, const Vec3& d) {
                                             b.v_w_b += d;
                                           }))),
            tol);
  EXPECT_LT(jacobianError(J.d_r_d_b_g, numericJacobian<9, 3>(residual_with(
                                           [](NavState&, NavState&, ImuBias& bb, const Vec3& d) {
                                             bb.b_g += d;
                                           }))),
            tol);
  EXPECT_LT(jacobianError(J.d_r_d_b_a, numericJacobian<9, 3>(residual_with(
                                           [](NavState&, NavState&, ImuBias& bb, const Vec3& d) {
                                             bb.b_a += d;
                                           }))),
            tol);
}

// Gravity: additive in g_w, and through the 2-DoF direction update R_w_g Exp([d_x, d_y, 0]).
TEST_F(ImuInertialResidualTest, GravityJacobiansMatchNumericDifferentiation) {
  const Mat3 R_w_g = gravityRotationFromDirection(Vec3(0.05, -0.08, -1.0));
  const Vec3 g_w = gravityFromRotation(R_w_g);
  const InertialResidualJacobians J =
      inertialResidualJacobians(state_i_, state_j_, linearisation_bias_, *pim_, g_w);
  const Mat93 numeric = numericJacobian<9, 3>([&](const Vec3& d) {
    return Vec9(inertialResidual(state_i_, state_j_, linearisation_bias_, *pim_, g_w + d));
  });
  EXPECT_LT(jacobianError(J.d_r_d_g_w, numeric), 1e-7);
  const Eigen::Matrix<double, 9, 2> numeric_dir = numericJacobian<9, 2>([&](const Vec2& d) {
    const Vec3 g = gravityFromRotation(updateGravityRotation(R_w_g, d));
    return Vec9(inertialResidual(state_i_, state_j_, linearisation_bias_, *pim_, g));
  });
  const Eigen::Matrix<double, 9, 2> analytic_dir = J.d_r_d_g_w * gravityJacobian(R_w_g);
  EXPECT_LT((analytic_dir - numeric_dir).cwiseAbs().maxCoeff(), 1e-6);
}

// SE3 chaining stated in the header: for T_w_b Exp([dphi; drho]), d_r_d_rho = d_r_d_p * R_w_b.
TEST_F(ImuInertialResidualTest, PositionJacobianChainsToSe3RightPerturbation) {
  const Vec3 g_w = gravityWorld();
  const InertialResidualJacobians J =
      inertialResidualJacobians(state_i_, state_j_, linearisation_bias_, *pim_, g_w);
  const Mat93 numeric = numericJacobian<9, 3>([&](const Vec3& d) {
    const SE3 T_w_b = SE3(state_i_.R_w_b, state_i_.p_w_b) * SE3::exp((Vec6() << Vec3::Zero(), d).finished());
    NavState a = state_i_;
    a.p_w_b = T_w_b.translation();
    a.R_w_b = T_w_b.rotationMatrix();
    return Vec9(inertialResidual(a, state_j_, linearisation_bias_, *pim_, g_w));
  });
  EXPECT_LT(jacobianError(Mat93(J.d_r_d_p_i * state_i_.R_w_b), numeric), 1e-7);
}

TEST(ImuGravity, RotationFromDirectionAndTwoDofJacobian) {
  for (const Vec3& dir : {Vec3(0.0, 0.0, -9.81), Vec3(0.1, -0.2, -1.0), Vec3(1.0, 0.5, 0.2),
                          Vec3(0.0, 0.0, 3.0), Vec3(1e-14, 0.0, 1.0)}) {
    const Mat3 R_w_g = gravityRotationFromDirection(dir);
    EXPECT_LT((R_w_g.transpose() * R_w_g - Mat3::Identity()).norm(), 1e-12);
    EXPECT_LT((gravityFromRotation(R_w_g, 1.0) - dir.normalized()).norm(), 1e-12) << dir.transpose();
    const Mat32 analytic = gravityJacobian(R_w_g);
    const Mat32 numeric = numericJacobian<3, 2>(
        [&](const Vec2& d) { return gravityFromRotation(updateGravityRotation(R_w_g, d)); });
    EXPECT_LT((analytic - numeric).cwiseAbs().maxCoeff(), 1e-6) << dir.transpose();
  }
  // Aligned gravity needs no rotation (no yaw is added).
  EXPECT_LT((gravityRotationFromDirection(Vec3(0.0, 0.0, -1.0)) - Mat3::Identity()).norm(), 1e-15);
}

}  // namespace
}  // namespace ltlo::imu
