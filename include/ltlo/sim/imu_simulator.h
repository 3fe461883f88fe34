#pragma once
/// IMU measurements from the analytic trajectory: body angular rate and specific force
/// f_b = R_w_b^T (a_w - g_w), g_w = (0, 0, -9.81), plus white noise and bias random walks
/// (discrete std = density * sqrt(rate) for noise, density / sqrt(rate) per step for walks).
/// A sensor profile adds the faults of a real IMU (ImuFaults): a time offset to the camera's clock,
/// scale factor and axis misalignment, stamp jitter, and accelerometer and gyroscope on their own clocks.
#include <cstdint>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/sim/robot_trajectory.h"
#include "ltlo/sim/sim_options.h"

namespace ltlo::sim {

constexpr double kGravityMps2 = 9.81;

struct ImuSample {
  double t_s = 0.0;  ///< stamp as written to imu.txt (the IMU's clock)
  Vec3 gyro_rad_s;   ///< measured angular rate, body frame
  Vec3 acc_mps2;     ///< measured specific force, body frame
  Vec3 bias_gyro;    ///< true gyro bias at t_s (ground truth)
  Vec3 bias_acc;     ///< true accelerometer bias at t_s
  /// Instant measured, on the true (camera) clock: t_s - time offset - jitter. For a half row, the
  /// instant of its half; for a merged row, the gyroscope's.
  double t_true_s = 0.0;
  bool has_gyro = true;  ///< false: an accelerometer-only sample (its gyro half is "nan" in imu.txt)
  bool has_acc = true;   ///< false: a gyroscope-only sample
};

/// Faults of a real IMU; the defaults are the ideal IMU (then the samples are exactly the ideal ones).
struct ImuFaults {
  double time_offset_s = 0.0;  ///< t_imu = t_cam + offset: a sample of true instant t is stamped t + offset
  bool intrinsics = false;     ///< apply M_gyro and M_acc
  Mat3 M_gyro = Mat3::Identity();  ///< measured rate = M_gyro omega_b + b_g + noise
  Mat3 M_acc = Mat3::Identity();   ///< measured force = M_acc f_b + b_a + noise
  double jitter_s = 0.0;       ///< stamp jitter std (s), Gaussian clipped at 3 sigma
  /// Gyroscope and accelerometer on their own clocks (half rows), at these rates; the first
  /// accelerometer stamp is acc_phase_s, the gyroscope's 0.
  bool separate_clocks = false;
  double gyro_rate_hz = 200.0, acc_rate_hz = 250.0, acc_phase_s = 0.0;
  /// With separate clocks: full rows at the gyroscope's stamps, the accelerometer interpolated
  /// linearly between its two neighbouring stamps (as drivers unite the streams).
  bool merged_rows = false;
};

/// Ideal IMU: samples at k / rate for k = 0 .. floor(duration * rate). Noise-free options give exact
/// values. With faults, stamps are k / rate (+ jitter) on the IMU's clock over [0, duration] and
/// measure the true instants stamp - offset; samples are in stamp order, stamps strictly increasing.
std::vector<ImuSample> simulateImu(const RobotTrajectory& trajectory, const SimOptions& options,
                                   const ImuFaults& faults = ImuFaults());

}  // namespace ltlo::sim
