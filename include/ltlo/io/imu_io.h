#pragma once
/// IMU sample streams: reading imu.txt (DATA_FORMAT.md), EuRoC imu0/data.csv and OpenLORIS
/// accel.txt + gyro.txt, gap checks, and cutting the stream into per-frame intervals.
#include <string>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/imu_sample.h"
#include "ltlo/core/sequence_options.h"

namespace ltlo::io {

/// One IMU reading in the body (IMU) frame: angular rate and specific force.
using ltlo::ImuSample;
using ltlo::ImuSamples;

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


}  // namespace ltlo::io
