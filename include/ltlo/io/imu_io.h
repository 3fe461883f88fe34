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

/// How every reader below treats the order of a file's rows (each sensor's rows on their own):
/// rows stamped before the latest stamp above them by at most options.max_imu_reorder_s are
/// sorted into time order (stable), a larger jump back throws InputError (file:line, the stamp and
/// the jump); of the rows sharing a stamp the first is kept, the others (same values or not) are
/// dropped; one warning per file gives the counts. Gaps between consecutive stamps longer than
/// options.max_imu_gap_s warn or throw according to options.imu_gap_policy. Nothing assumes an
/// even rate. Clean files (increasing stamps, no half rows) are read as written.

/// imu.txt: "timestamp gx gy gz ax ay az" (s, rad/s, m/s^2), '#' comments. Either triple may be
/// "nan nan nan" (any case) for a row of one sensor; a file with such half rows is a split stream:
/// full samples at the gyroscope's stamps (gyro-only and full rows), the accelerometer (accel-only
/// and full rows) linearly interpolated there, gyroscope samples outside the accelerometer's span
/// dropped (one info line). Throws InputError (file:line: value) on malformed lines, non-finite
/// values, partly nan triples and rows with both triples nan.
ImuSamples readImuText(const std::string& path, const SequenceOptions& options);

/// EuRoC imu0/data.csv: "timestamp_ns,w_x,w_y,w_z,a_x,a_y,a_z" (full rows only). Same checks as
/// readImuText.
ImuSamples readEurocImuCsv(const std::string& path, const SequenceOptions& options);

/// OpenLORIS accel.txt and gyro.txt ("timestamp x y z" each, different rates): each ordered and
/// checked as above, then merged by linear interpolation at the union of their timestamps inside
/// the interval both cover (one info line).
ImuSamples readOpenLorisImu(const std::string& accel_path, const std::string& gyro_path,
                            const SequenceOptions& options);

}  // namespace ltlo::io
