#pragma once
/// One IMU reading and interval cutting, shared by the readers (io), preintegration (imu) and the
/// simulator (sim).
#include <vector>

#include "ltlo/core/eigen_types.h"

namespace ltlo {

/// One IMU reading in the body (IMU) frame b.
struct ImuSample {
  double t_s = 0.0;                ///< timestamp (s)
  Vec3 gyro_rad_s = Vec3::Zero();  ///< angular rate of b w.r.t. the world, in b (rad/s)
  Vec3 acc_m_s2 = Vec3::Zero();    ///< specific force a - g in b (m/s^2); ~ (0, 0, +9.81) at rest, z up
};
using ImuSamples = std::vector<ImuSample>;

/// Linear interpolation between a and b at t_s (a.t_s <= t_s <= b.t_s).
ImuSample interpolateImuSample(const ImuSample& a, const ImuSample& b, double t_s);

/// Samples of `imu` (sorted, strictly increasing) in [t_begin_s, t_end_s], with interpolated samples
/// exactly at both ends, so consecutive intervals [t0, t1], [t1, t2] tile the time axis and share
/// their boundary sample. Ends outside the stream's coverage are clipped to it (no extrapolation);
/// an interval the stream does not reach gives no samples.
ImuSamples imuSamplesBetween(const ImuSamples& imu, double t_begin_s, double t_end_s);

}  // namespace ltlo
