#include "ltlo/sim/robot_trajectory.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "ltlo/core/errors.h"

namespace ltlo::sim {
namespace {

Mat3 rotX(double a) { return Eigen::AngleAxisd(a, Vec3::UnitX()).toRotationMatrix(); }
Mat3 rotY(double a) { return Eigen::AngleAxisd(a, Vec3::UnitY()).toRotationMatrix(); }
Mat3 rotZ(double a) { return Eigen::AngleAxisd(a, Vec3::UnitZ()).toRotationMatrix(); }

}  // namespace

RobotTrajectory::RobotTrajectory(const TrajectoryParams& params, uint64_t seed) : params_(params) {
  std::sort(params_.stills.begin(), params_.stills.end(),
            [](const StillInterval& a, const StillInterval& b) { return a.start_s < b.start_s; });
  const double ramp = params_.still_ramp_s;
  double free_from_s = 0.0;  // end of the previous interval's speed-up
  for (const StillInterval& still : params_.stills) {
    const std::string text = "--still " + std::to_string(still.start_s) + "," + std::to_string(still.duration_s);
    if (!(still.duration_s > 0.0) || !(still.start_s >= 0.0))
      throw InputError(text + ": expected START >= 0 and DURATION > 0 (s)");
    const bool at_start = still.start_s == 0.0;
    if (!at_start && still.start_s - ramp < free_from_s)
      throw InputError(text + ": the robot slows down over " + std::to_string(ramp) +
                       " s before a stop, so a stop starts at 0 or at least that long after the start or the "
                       "previous stop's speed-up");
    free_from_s = still.start_s + still.duration_s + ramp;
  }
  std::mt19937_64 rng(seed * 7919 + 17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
  radius_x_m_ = uniform(2.3, 2.45);
  radius_y_m_ = uniform(1.6, 1.75);
  harmonic_x_m_ = uniform(-0.15, 0.15);
  harmonic_y_m_ = uniform(-0.12, 0.12);
  harmonic_phase_ = uniform(0.0, 2.0 * M_PI);
  s0_ = uniform(0.0, 2.0 * M_PI);
  // Mean |dp/ds| over a lap gives the parameter rate for the requested mean speed.
  double mean_dp_ds = 0.0;
  const int kSteps = 2000;
  for (int i = 0; i < kSteps; ++i) {
    const double s = 2.0 * M_PI * i / kSteps;
    const double dx =
        -radius_x_m_ * std::sin(s) - 2.0 * harmonic_x_m_ * std::sin(2.0 * s + harmonic_phase_);
    const double dy =
        radius_y_m_ * std::cos(s) + 2.0 * harmonic_y_m_ * std::cos(2.0 * s + harmonic_phase_);
    mean_dp_ds += std::hypot(dx, dy) / kSteps;
  }
  omega0_ = params.mean_speed_mps / mean_dp_ds;
  speed_wobble_omega_ = 2.0 * M_PI / uniform(15.0, 25.0);
  speed_wobble_ = 0.05 * omega0_ / speed_wobble_omega_;  // +-5 % of the parameter rate
  for (std::vector<Sinusoid>* terms : {&roll_, &pitch_}) {
    for (double f_hz : {uniform(0.5, 1.2), uniform(1.8, 3.0)}) {
      terms->push_back({params.vibration_angle_rad * uniform(0.6, 1.0), 2.0 * M_PI * f_hz,
                        uniform(0.0, 2.0 * M_PI)});
    }
  }
  for (double f_hz : {uniform(1.0, 1.6), uniform(2.0, 3.0)}) {
    height_.push_back({params.vibration_height_m * uniform(0.6, 1.0), 2.0 * M_PI * f_hz,
                       uniform(0.0, 2.0 * M_PI)});
  }
}

void RobotTrajectory::evaluate(const std::vector<Sinusoid>& terms, double t_s, double* value,
                               double* rate, double* accel) {
  *value = *rate = *accel = 0.0;
  for (const Sinusoid& term : terms) {
    const double arg = term.omega_rad_s * t_s + term.phase_rad;
    *value += term.amplitude * std::sin(arg);
    *rate += term.amplitude * term.omega_rad_s * std::cos(arg);
    *accel -= term.amplitude * term.omega_rad_s * term.omega_rad_s * std::sin(arg);
  }
}

void RobotTrajectory::planar(double t_s, Vec2* p, Vec2* v, Vec2* a) const {
  const double w1 = speed_wobble_omega_;
  const double s = s0_ + omega0_ * t_s + speed_wobble_ * std::sin(w1 * t_s);
  const double s_dot = omega0_ + speed_wobble_ * w1 * std::cos(w1 * t_s);
  const double s_ddot = -speed_wobble_ * w1 * w1 * std::sin(w1 * t_s);
  const double h = harmonic_phase_;
  const Vec2 p_s(radius_x_m_ * std::cos(s) + harmonic_x_m_ * std::cos(2 * s + h),
                 radius_y_m_ * std::sin(s) + harmonic_y_m_ * std::sin(2 * s + h));
  const Vec2 dp_ds(-radius_x_m_ * std::sin(s) - 2 * harmonic_x_m_ * std::sin(2 * s + h),
                   radius_y_m_ * std::cos(s) + 2 * harmonic_y_m_ * std::cos(2 * s + h));
  const Vec2 d2p_ds2(-radius_x_m_ * std::cos(s) - 4 * harmonic_x_m_ * std::cos(2 * s + h),
                     -radius_y_m_ * std::sin(s) - 4 * harmonic_y_m_ * std::sin(2 * s + h));
  *p = p_s;
  *v = dp_ds * s_dot;
  *a = d2p_ds2 * s_dot * s_dot + dp_ds * s_ddot;
}

void RobotTrajectory::pathTime(double t_s, double* tau_s, double* rate, double* rate_dot) const {
  // Speed profile around a stop at S for D s with ramp r: tau' = 1 - s(u) over the slow-down
  // [S - r, S], 0 while still, s(u) over the speed-up [S + D, S + D + r], with the smoothstep
  // s(u) = 3u^2 - 2u^3; the path time lost is the integral of 1 - tau'.
  const double r = params_.still_ramp_s;
  auto smooth = [](double u) { return u * u * (3.0 - 2.0 * u); };
  auto smooth_rate = [](double u) { return 6.0 * u * (1.0 - u); };
  auto smooth_integral = [](double u) { return u * u * u * (1.0 - 0.5 * u); };  // of s over [0, u]
  double lost_s = 0.0;
  *rate = 1.0;
  *rate_dot = 0.0;
  for (const StillInterval& still : params_.stills) {
    const bool at_start = still.start_s == 0.0;
    const double slow_from = at_start ? 0.0 : still.start_s - r;
    const double end = still.start_s + still.duration_s;
    if (t_s < slow_from) break;
    if (!at_start) {
      if (t_s < still.start_s) {
        const double u = (t_s - slow_from) / r;
        lost_s += r * smooth_integral(u);
        *rate = 1.0 - smooth(u);
        *rate_dot = -smooth_rate(u) / r;
        break;
      }
      lost_s += 0.5 * r;
    }
    if (t_s <= end) {
      lost_s += t_s - still.start_s;
      *rate = 0.0;
      break;
    }
    lost_s += still.duration_s;
    if (t_s < end + r) {
      const double u = (t_s - end) / r;
      lost_s += r * (u - smooth_integral(u));
      *rate = smooth(u);
      *rate_dot = smooth_rate(u) / r;
      break;
    }
    lost_s += 0.5 * r;
  }
  *tau_s = t_s - lost_s;
}

double RobotTrajectory::pathTimeAt(double t_s) const {
  double tau_s, rate, rate_dot;
  pathTime(t_s, &tau_s, &rate, &rate_dot);
  return tau_s;
}

SE3 RobotTrajectory::T_w_floor(double t_s) const {
  double tau_s, rate, rate_dot;
  pathTime(t_s, &tau_s, &rate, &rate_dot);
  Vec2 p, v, a;
  planar(tau_s, &p, &v, &a);
  return SE3(rotZ(std::atan2(v.y(), v.x())), Vec3(p.x(), p.y(), 0.0));
}

RobotState RobotTrajectory::state(double t_s) const {
  double tau_s, rate, rate_dot;
  pathTime(t_s, &tau_s, &rate, &rate_dot);
  RobotState state = movingState(tau_s);
  state.t_s = t_s;
  if (rate == 1.0 && rate_dot == 0.0) return state;  // moving: exactly the path's state
  // p(t) = p_m(tau(t)): v = v_m tau', a = a_m tau'^2 + v_m tau'', omega_b = omega_m tau'.
  state.a_w_b = state.a_w_b * (rate * rate) + state.v_w_b * rate_dot;
  state.v_w_b *= rate;
  state.omega_b *= rate;
  return state;
}

RobotState RobotTrajectory::movingState(double t_s) const {
  Vec2 p, v, a;
  planar(t_s, &p, &v, &a);
  const double yaw = std::atan2(v.y(), v.x());
  const double yaw_rate = (v.x() * a.y() - v.y() * a.x()) / v.squaredNorm();
  double roll, roll_rate, roll_accel, pitch, pitch_rate, pitch_accel, dz, dz_rate, dz_accel;
  evaluate(roll_, t_s, &roll, &roll_rate, &roll_accel);
  evaluate(pitch_, t_s, &pitch, &pitch_rate, &pitch_accel);
  evaluate(height_, t_s, &dz, &dz_rate, &dz_accel);

  // R_w_b = Rz(yaw) Ry(pitch) Rx(roll); omega_b = Rx^T Ry^T yaw_rate e_z + Rx^T pitch_rate e_y
  // + roll_rate e_x (from R^T dR/dt = hat(omega_b)).
  const Mat3 Rx = rotX(roll), Ry = rotY(pitch);
  RobotState state;
  state.t_s = t_s;
  state.T_w_b = SE3(rotZ(yaw) * Ry * Rx, Vec3(p.x(), p.y(), params_.body_height_m + dz));
  state.v_w_b = Vec3(v.x(), v.y(), dz_rate);
  state.a_w_b = Vec3(a.x(), a.y(), dz_accel);
  state.omega_b = Rx.transpose() * Ry.transpose() * Vec3(0, 0, yaw_rate) +
                  Rx.transpose() * Vec3(0, pitch_rate, 0) + Vec3(roll_rate, 0, 0);
  return state;
}

double RobotTrajectory::pathLength(double duration_s) const {
  double length_m = 0.0;
  Vec3 previous = state(0.0).T_w_b.translation();
  for (double t = 1e-3; t <= duration_s + 1e-9; t += 1e-3) {
    const Vec3 current = state(t).T_w_b.translation();
    length_m += (current - previous).norm();
    previous = current;
  }
  return length_m;
}

}  // namespace ltlo::sim
