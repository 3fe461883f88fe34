#pragma once
/// Analytic trajectory of a wheeled robot: a closed, smooth curve around the room (lap after lap,
/// so places are revisited) with sinusoidal speed variation, heading along the path, and small
/// roll/pitch/height vibration. Position, velocity, acceleration, orientation and body angular
/// rate are closed-form, so the simulated IMU is exact.
#include <cstdint>
#include <vector>

#include "ltlo/core/lie.h"

namespace ltlo::sim {

struct RobotState {
  double t_s = 0.0;
  SE3 T_w_b;     ///< body (IMU) pose; world z up, body x forward, y left, z up
  Vec3 v_w_b;    ///< body velocity in the world (m/s)
  Vec3 a_w_b;    ///< body acceleration in the world (m/s^2)
  Vec3 omega_b;  ///< angular rate in the body frame (rad/s)
};

/// A stretch where the robot stands still (simulate --still START,DURATION): the pose is held
/// exactly over [start_s, start_s + duration_s]; the robot slows down over the ramp before it (none
/// when start_s = 0: it starts at rest) and speeds up over the ramp after it (smoothstep speed
/// profiles, so the acceleration stays continuous), then goes on along the path where it stopped.
struct StillInterval {
  double start_s = 0.0;
  double duration_s = 0.0;
  bool covers(double t_s) const { return t_s >= start_s && t_s <= start_s + duration_s; }
};

struct TrajectoryParams {
  double mean_speed_mps = 0.45;
  double vibration_angle_rad = 0.02;
  double vibration_height_m = 0.004;
  double body_height_m = 0.35;  ///< IMU height above the floor
  std::vector<StillInterval> stills;  ///< sorted, apart by more than two ramps (checked)
  double still_ramp_s = 1.0;          ///< duration of the slow-down and of the speed-up (s)
};

class RobotTrajectory {
 public:
  /// Throws InputError when still intervals overlap (ramps included) or one starts within a ramp
  /// of 0 but not at 0.
  RobotTrajectory(const TrajectoryParams& params, uint64_t seed);

  RobotState state(double t_s) const;
  /// Vibration-free pose on the floor (yaw only, z = 0): the frame pushed boxes move with.
  SE3 T_w_floor(double t_s) const;
  /// Path time at sequence time t_s: t_s less the time lost in still intervals and their ramps
  /// (what has stood still stays the same while the robot stands).
  double pathTimeAt(double t_s) const;
  /// Path length of the body over [0, duration_s] (numerical, 1 ms steps).
  double pathLength(double duration_s) const;

 private:
  struct Sinusoid {
    double amplitude, omega_rad_s, phase_rad;
  };
  /// Path time tau(t) of the moving robot at sequence time t and its first two derivatives (1, 0
  /// outside still intervals and their ramps; 0, 0 while still).
  void pathTime(double t_s, double* tau_s, double* rate, double* rate_dot) const;
  RobotState movingState(double tau_s) const;
  void planar(double t_s, Vec2* p, Vec2* v, Vec2* a) const;
  static void evaluate(const std::vector<Sinusoid>& terms, double t_s, double* value, double* rate,
                       double* accel);

  TrajectoryParams params_;
  double radius_x_m_, radius_y_m_;  // ellipse semi-axes
  double harmonic_x_m_, harmonic_y_m_, harmonic_phase_;
  double omega0_, speed_wobble_, speed_wobble_omega_, s0_;
  std::vector<Sinusoid> roll_, pitch_, height_;
};

}  // namespace ltlo::sim
