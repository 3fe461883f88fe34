#include "ltlo/imu/inertial_residual.h"

#include <cmath>

#include "ltlo/core/assert.h"
#include "ltlo/core/lie.h"

namespace ltlo::imu {

NavState predict(const NavState& state_i, const Preintegrated& pim, const ImuBias& bias,
                 const Vec3& g_w) {
  const double dt = pim.dt_s();
  const Mat3& R_i = state_i.R_w_b;
  NavState state_j;
  state_j.R_w_b = normalizeRotation(R_i * pim.correctedDeltaR(bias));
  state_j.v_w_b = state_i.v_w_b + g_w * dt + R_i * pim.correctedDeltaV(bias);
  state_j.p_w_b = state_i.p_w_b + state_i.v_w_b * dt + 0.5 * dt * dt * g_w +
                  R_i * pim.correctedDeltaP(bias);
  return state_j;
}

namespace {

/// The parts of the residual that its Jacobians reuse.
struct ResidualParts {
  Mat3 delta_R;        // bias-corrected delta_R
  Vec3 r_R, r_v, r_p;
  Vec3 dv_body;        // R_i^T (v_j - v_i - g dt)
  Vec3 dp_body;        // R_i^T (p_j - p_i - v_i dt - g dt^2/2)
};

ResidualParts residualParts(const NavState& state_i, const NavState& state_j, const ImuBias& bias,
                            const Preintegrated& pim, const Vec3& g_w) {
  const double dt = pim.dt_s();
  const Mat3 R_i_T = state_i.R_w_b.transpose();
  ResidualParts parts;
  parts.delta_R = pim.correctedDeltaR(bias);
  parts.dv_body = R_i_T * (state_j.v_w_b - state_i.v_w_b - g_w * dt);
  parts.dp_body =
      R_i_T * (state_j.p_w_b - state_i.p_w_b - state_i.v_w_b * dt - 0.5 * dt * dt * g_w);
  parts.r_R = so3Log(Mat3(parts.delta_R.transpose() * R_i_T * state_j.R_w_b));
  parts.r_v = parts.dv_body - pim.correctedDeltaV(bias);
  parts.r_p = parts.dp_body - pim.correctedDeltaP(bias);
  return parts;
}

}  // namespace

Vec9 inertialResidual(const NavState& state_i, const NavState& state_j, const ImuBias& bias,
                      const Preintegrated& pim, const Vec3& g_w) {
  const ResidualParts parts = residualParts(state_i, state_j, bias, pim, g_w);
  Vec9 r;
  r << parts.r_R, parts.r_v, parts.r_p;
  return r;
}

InertialResidualJacobians inertialResidualJacobians(const NavState& state_i,
                                                    const NavState& state_j, const ImuBias& bias,
                                                    const Preintegrated& pim, const Vec3& g_w) {
  const double dt = pim.dt_s();
  const ResidualParts parts = residualParts(state_i, state_j, bias, pim, g_w);
  const Mat3 R_i_T = state_i.R_w_b.transpose();
  const Mat3 J_r_inv = so3RightJacobianInverse(parts.r_R);
  const Vec3 bias_change_g = bias.b_g - pim.bias().b_g;

  InertialResidualJacobians out;
  out.residual << parts.r_R, parts.r_v, parts.r_p;
  for (Mat93* J : {&out.d_r_d_R_i, &out.d_r_d_p_i, &out.d_r_d_v_i, &out.d_r_d_R_j, &out.d_r_d_p_j,
                   &out.d_r_d_v_j, &out.d_r_d_b_g, &out.d_r_d_b_a, &out.d_r_d_g_w}) {
    J->setZero();
  }

  // Rotation residual: Log(dR^T R_i^T R_j).
  out.d_r_d_R_i.block<3, 3>(0, 0) = -J_r_inv * state_j.R_w_b.transpose() * state_i.R_w_b;
  out.d_r_d_R_j.block<3, 3>(0, 0) = J_r_inv;
  // dR(b_g + e) = dR(b_g) Exp(J_r(d_R_d_b_g db) d_R_d_b_g e) to first order in e.
  out.d_r_d_b_g.block<3, 3>(0, 0) = -J_r_inv * so3Exp(parts.r_R).transpose() *
                                    so3RightJacobian(pim.d_R_d_b_g() * bias_change_g) *
                                    pim.d_R_d_b_g();

  // Velocity residual.
  out.d_r_d_R_i.block<3, 3>(3, 0) = hat(parts.dv_body);
  out.d_r_d_v_i.block<3, 3>(3, 0) = -R_i_T;
  out.d_r_d_v_j.block<3, 3>(3, 0) = R_i_T;
  out.d_r_d_b_g.block<3, 3>(3, 0) = -pim.d_v_d_b_g();
  out.d_r_d_b_a.block<3, 3>(3, 0) = -pim.d_v_d_b_a();

  // Position residual.
  out.d_r_d_R_i.block<3, 3>(6, 0) = hat(parts.dp_body);
  out.d_r_d_p_i.block<3, 3>(6, 0) = -R_i_T;
  out.d_r_d_v_i.block<3, 3>(6, 0) = -R_i_T * dt;
  out.d_r_d_p_j.block<3, 3>(6, 0) = R_i_T;
  out.d_r_d_b_g.block<3, 3>(6, 0) = -pim.d_p_d_b_g();
  out.d_r_d_b_a.block<3, 3>(6, 0) = -pim.d_p_d_b_a();

  // Gravity.
  out.d_r_d_g_w.block<3, 3>(3, 0) = -R_i_T * dt;
  out.d_r_d_g_w.block<3, 3>(6, 0) = -R_i_T * (0.5 * dt * dt);
  return out;
}

Mat3 gravityRotationFromDirection(const Vec3& gravity_dir_w) {
  const double norm = gravity_dir_w.norm();
  LTLO_ASSERT(norm > 0.0 && std::isfinite(norm),
              "gravity direction must be finite and non-zero, got " << gravity_dir_w.transpose());
  const Vec3 dir = gravity_dir_w / norm;
  const Vec3 down(0.0, 0.0, -1.0);
  // Minimal rotation taking `down` to `dir`; near-opposite directions rotate by pi about x.
  const Vec3 axis = down.cross(dir);
  const double sin_angle = axis.norm();
  const double cos_angle = down.dot(dir);
  if (sin_angle < 1e-12) {
    return cos_angle > 0.0 ? Mat3::Identity() : so3Exp(Vec3(M_PI, 0.0, 0.0));
  }
  return so3Exp(axis / sin_angle * std::atan2(sin_angle, cos_angle));
}

Vec3 gravityFromRotation(const Mat3& R_w_g, double gravity_m_s2) {
  return R_w_g * Vec3(0.0, 0.0, -gravity_m_s2);
}

Mat3 updateGravityRotation(const Mat3& R_w_g, const Vec2& delta_xy) {
  return normalizeRotation(R_w_g * so3Exp(Vec3(delta_xy.x(), delta_xy.y(), 0.0)));
}

Mat32 gravityJacobian(const Mat3& R_w_g, double gravity_m_s2) {
  // R Exp(d) g0 ~ R g0 - R g0^ d: the first two columns of -R g0^.
  const Mat3 full = -R_w_g * hat(Vec3(0.0, 0.0, -gravity_m_s2));
  return full.leftCols<2>();
}

}  // namespace ltlo::imu
