#include "ltlo/imu/imu_types.h"

#include <cmath>

#include "ltlo/core/assert.h"

namespace ltlo::imu {

ImuNoise ImuNoise::fromCalib(const ImuCalib& calib) {
  LTLO_ASSERT(calib.rate_hz > 0.0, "IMU rate must be positive, got " << calib.rate_hz);
  ImuNoise noise;
  noise.gyro_density = calib.noise_gyro;
  noise.acc_density = calib.noise_acc;
  noise.gyro_walk_density = calib.gyro_walk;
  noise.acc_walk_density = calib.acc_walk;
  noise.nominal_dt_s = 1.0 / calib.rate_hz;
  return noise;
}

Mat3 ImuNoise::gyroCovariance(double dt_s) const {
  LTLO_ASSERT(dt_s > 0.0, "step dt must be positive, got " << dt_s);
  return Mat3::Identity() * (gyro_density * gyro_density / dt_s);
}

Mat3 ImuNoise::accCovariance(double dt_s) const {
  LTLO_ASSERT(dt_s > 0.0, "step dt must be positive, got " << dt_s);
  return Mat3::Identity() * (acc_density * acc_density / dt_s);
}

Mat6 ImuNoise::biasWalkCovariance(double interval_s) const {
  LTLO_ASSERT(interval_s >= 0.0, "interval must be non-negative, got " << interval_s);
  Mat6 cov = Mat6::Zero();
  cov.topLeftCorner<3, 3>() = Mat3::Identity() * (gyro_walk_density * gyro_walk_density * interval_s);
  cov.bottomRightCorner<3, 3>() = Mat3::Identity() * (acc_walk_density * acc_walk_density * interval_s);
  return cov;
}

std::vector<ImuSample> samplesInInterval(const std::vector<ImuSample>& samples, double t_begin_s,
                                         double t_end_s) {
  LTLO_ASSERT(t_begin_s <= t_end_s, "interval [" << t_begin_s << ", " << t_end_s << "] reversed");
  LTLO_ASSERT(!samples.empty() && samples.front().t_s <= t_begin_s && samples.back().t_s >= t_end_s,
              "samples do not cover [" << t_begin_s << ", " << t_end_s << "]");
  return imuSamplesBetween(samples, t_begin_s, t_end_s);
}

}  // namespace ltlo::imu
