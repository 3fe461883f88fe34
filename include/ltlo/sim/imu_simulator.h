#pragma once
/// IMU measurements from the analytic trajectory: body angular rate and specific force
/// f_b = R_w_b^T (a_w - g_w), g_w = (0, 0, -9.81), plus white noise and bias random walks
/// (discrete std = density * sqrt(rate) for noise, density / sqrt(rate) per step for walks).
#include <cstdint>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/sim/robot_trajectory.h"
#include "ltlo/sim/sim_options.h"

namespace ltlo::sim {

constexpr double kGravityMps2 = 9.81;

struct ImuSample {
  double t_s = 0.0;
  Vec3 gyro_rad_s;  ///< measured angular rate, body frame
  Vec3 acc_mps2;    ///< measured specific force, body frame
  Vec3 bias_gyro;   ///< true gyro bias at t_s (ground truth)
  Vec3 bias_acc;    ///< true accelerometer bias at t_s
};

/// Samples at k / rate for k = 0 .. floor(duration * rate). Noise-free options give exact values.
std::vector<ImuSample> simulateImu(const RobotTrajectory& trajectory, const SimOptions& options);

}  // namespace ltlo::sim
