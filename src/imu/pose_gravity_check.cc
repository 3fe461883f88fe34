#include "ltlo/imu/pose_gravity_check.h"

#include <algorithm>
#include <cmath>

#include "ltlo/core/assert.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/inertial_residual.h"

namespace ltlo::imu {

namespace {

/// A window closes within this of window_s (three frame intervals of 1/30 s add up to 0.1 s less
/// rounding), s.
constexpr double kWindowToleranceS = 1e-3;

/// `interval` followed by (dR, dV, dP, dt): the preintegration's composition.
void append(PoseGravityCheck::Interval* interval, const Mat3& dR, const Vec3& dV, const Vec3& dP, double dt_s) {
  interval->dP += interval->dV * dt_s + interval->dR * dP;
  interval->dV += interval->dR * dV;
  interval->dR = normalizeRotation(interval->dR * dR);
  interval->dt_s += dt_s;
}

/// g_w of the window a, b, c (see the header's identity).
Vec3 windowGravity(const PoseGravityCheck::Node& a, const PoseGravityCheck::Node& b, const PoseGravityCheck::Node& c,
                   const PoseGravityCheck::Interval& ab, const PoseGravityCheck::Interval& bc) {
  const double dt0 = ab.dt_s, dt1 = bc.dt_s;
  const Vec3 m = (c.p_w_b - b.p_w_b) / dt1 - (b.p_w_b - a.p_w_b) / dt0 - b.R_w_b * bc.dP / dt1 +
                 a.R_w_b * ab.dP / dt0 - a.R_w_b * ab.dV;
  return m / (0.5 * (dt0 + dt1));
}

/// Standard deviation of one axis of windowGravity from the positions' sigmas (independent).
double windowSigma(const PoseGravityCheck::Node& a, const PoseGravityCheck::Node& b, const PoseGravityCheck::Node& c,
                   const PoseGravityCheck::Interval& ab, const PoseGravityCheck::Interval& bc) {
  const double dt0 = ab.dt_s, dt1 = bc.dt_s;
  const double sa = a.sigma_m / dt0, sb = b.sigma_m * (1.0 / dt0 + 1.0 / dt1), sc = c.sigma_m / dt1;
  return std::sqrt(sa * sa + sb * sb + sc * sc) / (0.5 * (dt0 + dt1));
}

}  // namespace

void PoseGravityCheck::reset() { state_ = State(); }

PoseGravityVerdict PoseGravityCheck::add(double t_s, const SE3& T_w_b, double sigma_m, const Mat3& dR,
                                         const Vec3& dV, const Vec3& dP, double dt_s) {
  LTLO_ASSERT(std::isfinite(sigma_m) && sigma_m >= 0.0, "position sigma " << sigma_m << " m");
  PoseGravityVerdict verdict;
  const Node node{t_s, T_w_b.rotationMatrix(), T_w_b.translation(), sigma_m};
  if (state_.nodes.empty()) {
    state_.nodes.push_back(node);
    state_.open = Interval();
    return verdict;
  }
  LTLO_ASSERT(dt_s > 0.0 && t_s > state_.nodes.back().t_s, "pose at t = " << t_s << " s with an IMU interval of "
                                                                           << dt_s << " s");
  append(&state_.open, dR, dV, dP, dt_s);
  if (state_.open.dt_s < options_.window_s - kWindowToleranceS) return verdict;
  state_.nodes.push_back(node);
  state_.intervals.push_back(state_.open);
  state_.open = Interval();
  if (state_.nodes.size() > 3) {
    state_.nodes.erase(state_.nodes.begin());
    state_.intervals.erase(state_.intervals.begin());
  }
  if (state_.nodes.size() < 3) return verdict;
  verdict.checked = true;
  verdict.g_w = windowGravity(state_.nodes[0], state_.nodes[1], state_.nodes[2], state_.intervals[0],
                              state_.intervals[1]);
  verdict.error_m_s2 = state_.windows == 0 ? std::abs(verdict.g_w.norm() - kGravity_m_s2)
                                           : (verdict.g_w - state_.g_sum / state_.windows).norm();
  verdict.bound_m_s2 = std::max(options_.max_error_m_s2,
                                options_.noise_sigmas * windowSigma(state_.nodes[0], state_.nodes[1], state_.nodes[2],
                                                                    state_.intervals[0], state_.intervals[1]));
  verdict.consistent = verdict.error_m_s2 <= verdict.bound_m_s2;
  state_.max_error_m_s2 = std::max(state_.max_error_m_s2, verdict.error_m_s2);
  if (verdict.consistent) {
    state_.g_sum += verdict.g_w;
    ++state_.windows;
  }
  return verdict;
}

}  // namespace ltlo::imu
