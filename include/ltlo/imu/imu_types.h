#pragma once
/// IMU measurements, biases and the discrete noise model used by preintegration (namespace ltlo::imu).
#include <vector>

#include "ltlo/core/calib.h"
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/imu_sample.h"

namespace ltlo::imu {

using ltlo::ImuSample;

/// Gyroscope and accelerometer biases: measurement = true value + bias + noise.
struct ImuBias {
  Vec3 b_g = Vec3::Zero();  ///< gyroscope bias (rad/s)
  Vec3 b_a = Vec3::Zero();  ///< accelerometer bias (m/s^2)
};

/// What a rest of the body tells of the IMU (issue 32): gravity in the world, g_w = -R_w_b f_mean
/// (the mean specific force at rest, accelerometer bias absorbed), and the gyroscope bias, the mean
/// gyro reading, both over rest_s seconds of readings.
struct RestEstimate {
  Vec3 g_w = Vec3::Zero();  ///< m/s^2, in the world of the pose it was taken at
  Vec3 b_g = Vec3::Zero();  ///< rad/s
  double rest_s = 0.0;      ///< s of readings averaged
};

/// Shortest interval a bias random-walk term is weighed over, s: two keyframes or frames closer than
/// this (repeated stamps) would give the walk an unbounded information. Every user of
/// ImuNoise::biasWalkCovariance as a factor (the optimiser's inertial edges, the dense solver's
/// IMU prior) clamps to this one floor.
constexpr double kMinBiasWalkInterval_s = 1e-3;

/// Discrete-time noise of one integration step, from the continuous-time densities of ImuCalib.
///
/// White measurement noise of density sigma_c (unit/sqrt(Hz)) sampled over a step of dt_s has the
/// discrete covariance sigma_c^2 / dt_s per axis; a bias random walk of density sigma_w grows by
/// sigma_w^2 * dt_s per axis over dt_s. Preintegration evaluates these with each step's actual dt_s
/// (the interpolated end steps of an interval are shorter than the nominal 1 / rate_hz).
struct ImuNoise {
  double gyro_density = 1.7e-4;      ///< rad/s/sqrt(Hz)    (ImuCalib::noise_gyro)
  double acc_density = 2.0e-3;       ///< m/s^2/sqrt(Hz)    (ImuCalib::noise_acc)
  double gyro_walk_density = 1.9e-5; ///< rad/s^2/sqrt(Hz)  (ImuCalib::gyro_walk)
  double acc_walk_density = 3.0e-3;  ///< m/s^3/sqrt(Hz)    (ImuCalib::acc_walk)
  double nominal_dt_s = 0.005;       ///< 1 / ImuCalib::rate_hz (s)

  static ImuNoise fromCalib(const ImuCalib& calib);

  /// Discrete covariance of one gyro (rad/s)^2 / accelerometer (m/s^2)^2 sample over dt_s.
  Mat3 gyroCovariance(double dt_s) const;
  Mat3 accCovariance(double dt_s) const;
  /// Same at the nominal sample period (the per-sample standard deviation is sqrt of this).
  Mat3 gyroCovariance() const { return gyroCovariance(nominal_dt_s); }
  Mat3 accCovariance() const { return accCovariance(nominal_dt_s); }
  /// Covariance of the bias change over an interval of interval_s, order [b_g; b_a].
  Mat6 biasWalkCovariance(double interval_s) const;
};

/// The samples covering exactly [t_begin_s, t_end_s]: the samples strictly inside plus interpolated
/// samples at both ends (an existing sample at an end is kept as is). `samples` must be sorted by
/// time and cover the interval; asserts otherwise.
std::vector<ImuSample> samplesInInterval(const std::vector<ImuSample>& samples, double t_begin_s,
                                         double t_end_s);

}  // namespace ltlo::imu
