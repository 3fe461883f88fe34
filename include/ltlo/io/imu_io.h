#pragma once
/// IMU sample streams: reading imu.txt (DATA_FORMAT.md), EuRoC imu0/data.csv and OpenLORIS
/// accel.txt + gyro.txt, gap checks, and cutting the stream into per-frame intervals.
#include <string>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/sequence_options.h"

namespace ltlo::io {

/// One IMU reading in the body (IMU) frame: angular rate and specific force.
struct ImuSample {
  double t_s = 0.0;
  Vec3 gyro_rad_s = Vec3::Zero();
  Vec3 acc_m_s2 = Vec3::Zero();
};
using ImuSamples = std::vector<ImuSample>;

/// imu.txt: "timestamp gx gy gz ax ay az" (s, rad/s, m/s^2), '#' comments. Throws InputError
/// (file:line: value) on malformed lines, non-finite values and non-increasing timestamps; gaps
/// longer than options.max_imu_gap_s warn or throw according to options.imu_gap_policy.
ImuSamples readImuText(const std::string& path, const SequenceOptions& options);

/// EuRoC imu0/data.csv: "timestamp_ns,w_x,w_y,w_z,a_x,a_y,a_z". Same checks as readImuText.
ImuSamples readEurocImuCsv(const std::string& path, const SequenceOptions& options);

/// OpenLORIS accel.txt and gyro.txt ("timestamp x y z" each, different rates): both are checked
/// as above, then merged by linear interpolation at the union of their timestamps inside the
/// interval both cover.
ImuSamples readOpenLorisImu(const std::string& accel_path, const std::string& gyro_path,
                            const SequenceOptions& options);

/// Linear interpolation between a and b at t_s (a.t_s <= t_s <= b.t_s, a.t_s < b.t_s).
ImuSample interpolateImu(const ImuSample& a, const ImuSample& b, double t_s);

/// Samples of `imu` (sorted, strictly increasing) in [t_begin_s, t_end_s], with interpolated
/// samples exactly at both ends, so consecutive intervals [t0, t1], [t1, t2] tile the time axis
/// and share their boundary sample. Ends outside the stream's coverage are clipped to it (no
/// extrapolation); an interval the stream does not reach gives no samples.
ImuSamples imuBetween(const ImuSamples& imu, double t_begin_s, double t_end_s);

}  // namespace ltlo::io
