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

struct TrajectoryParams {
  double mean_speed_mps = 0.45;
  double vibration_angle_rad = 0.02;
  double vibration_height_m = 0.004;
  double body_height_m = 0.35;  ///< IMU height above the floor
};

class RobotTrajectory {
 public:
  RobotTrajectory(const TrajectoryParams& params, uint64_t seed);

  RobotState state(double t_s) const;
  /// Vibration-free pose on the floor (yaw only, z = 0): the frame pushed boxes move with.
  SE3 T_w_floor(double t_s) const;
  /// Path length of the body over [0, duration_s] (numerical, 1 ms steps).
  double pathLength(double duration_s) const;

 private:
  struct Sinusoid {
    double amplitude, omega_rad_s, phase_rad;
  };
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
