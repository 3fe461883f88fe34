#pragma once
/// Prediction and the inertial-edge residual with analytic Jacobians: the one place for this maths
/// (tracking, local BA, IMU initialisation and full BA wrap these functions in sparse_opt edges).
///
/// Perturbation conventions of the Jacobians:
///   R_w_b  <- R_w_b Exp(dphi)   (right perturbation, dphi in the body frame)
///   p_w_b  <- p_w_b + dp        (additive, world frame)
///   v_w_b  <- v_w_b + dv        (additive, world frame)
///   b_g, b_a <- b + db          (additive)
/// For an SE3 vertex updated as T_w_b Exp([dphi; drho]) (rotation first), chain with
/// dp = R_w_b drho to first order: d_r_d_rho = d_r_d_p * R_w_b.
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/preintegration.h"

namespace ltlo::imu {

using Mat93 = Eigen::Matrix<double, 9, 3>;
using Mat32 = Eigen::Matrix<double, 3, 2>;

/// Body state in a gravity-aligned world w.
struct NavState {
  Mat3 R_w_b = Mat3::Identity();
  Vec3 p_w_b = Vec3::Zero();   ///< m
  Vec3 v_w_b = Vec3::Zero();   ///< m/s, body velocity in world
};

/// The state of a body pose T_w_b moving at v_w_b.
inline NavState navState(const SE3& T_w_b, const Vec3& v_w_b) {
  NavState state;
  state.R_w_b = T_w_b.rotationMatrix();
  state.p_w_b = T_w_b.translation();
  state.v_w_b = v_w_b;
  return state;
}

/// Standard gravity in a z-up gravity-aligned world (m/s^2).
constexpr double kGravity_m_s2 = 9.81;
inline Vec3 gravityWorld() { return Vec3(0.0, 0.0, -kGravity_m_s2); }

/// State at j predicted from the state at i with the deltas corrected for `bias`:
///   R_j = R_i dR,  v_j = v_i + g dt + R_i dv,  p_j = p_i + v_i dt + g dt^2/2 + R_i dp.
NavState predict(const NavState& state_i, const Preintegrated& pim, const ImuBias& bias,
                 const Vec3& g_w);

/// Residual r = [Log(dR^T R_i^T R_j); R_i^T (v_j - v_i - g dt) - dv;
///               R_i^T (p_j - p_i - v_i dt - g dt^2/2) - dp], deltas corrected for `bias`.
Vec9 inertialResidual(const NavState& state_i, const NavState& state_j, const ImuBias& bias,
                      const Preintegrated& pim, const Vec3& g_w);

/// Residual and its Jacobians (9x3 each, conventions in the file comment).
struct InertialResidualJacobians {
  Vec9 residual;
  Mat93 d_r_d_R_i, d_r_d_p_i, d_r_d_v_i;
  Mat93 d_r_d_R_j, d_r_d_p_j, d_r_d_v_j;
  Mat93 d_r_d_b_g, d_r_d_b_a;
  /// W.r.t. gravity g_w (additive); for the 2-DoF gravity direction of IMU initialisation chain
  /// with gravityJacobian(R_w_g): d_r_d_g_dir = d_r_d_g_w * gravityJacobian(R_w_g).
  Mat93 d_r_d_g_w;
};
InertialResidualJacobians inertialResidualJacobians(const NavState& state_i,
                                                    const NavState& state_j, const ImuBias& bias,
                                                    const Preintegrated& pim, const Vec3& g_w);

// ---- Gravity direction (IMU initialisation) ------------------------------------------------
// The world w is gravity-aligned by R_w_g: g_w = R_w_g (0, 0, -G). Only two degrees of freedom are
// observable (yaw about gravity is not), so R_w_g is updated as R_w_g Exp([d_x, d_y, 0]).

/// A rotation R_w_g with R_w_g (0, 0, -1) = direction of gravity in w (`gravity_dir_w` need not be
/// unit; the minimal rotation, no yaw). E.g. from the mean specific force f_w: gravity_dir_w = -f_w.
Mat3 gravityRotationFromDirection(const Vec3& gravity_dir_w);
/// g_w = R_w_g (0, 0, -gravity_m_s2).
Vec3 gravityFromRotation(const Mat3& R_w_g, double gravity_m_s2 = kGravity_m_s2);
/// R_w_g Exp([d_x, d_y, 0]).
Mat3 updateGravityRotation(const Mat3& R_w_g, const Vec2& delta_xy);
/// d g_w / d [d_x, d_y] at delta = 0.
Mat32 gravityJacobian(const Mat3& R_w_g, double gravity_m_s2 = kGravity_m_s2);

}  // namespace ltlo::imu
