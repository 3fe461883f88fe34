#pragma once
/// Trajectory files: TUM ("timestamp tx ty tz qx qy qz qw", seconds) and EuRoC CSV
/// ("timestamp_ns,px,py,pz,qw,qx,qy,qz", nanoseconds). Readers accept CRLF line ends, '#' comments
/// and blank lines, normalise quaternions (one warning per file for norms off 1 by more than 1e-3)
/// and throw InputError naming the file, the line and the value (malformed lines, non-finite
/// values, zero quaternions, non-increasing times). Writers keep full precision (timestamps with 9
/// decimals) and replace the file only once it is complete ("<path>.part" renamed over it).
#include <string>
#include <vector>

#include "ltlo/core/lie.h"

namespace ltlo::io {

/// One pose of a trajectory: T_w_x at time t_s (x = camera for trajectory.txt).
struct StampedPose {
  double t_s = 0.0;
  SE3 T_w_x;
};
using Trajectory = std::vector<StampedPose>;

Trajectory readTumTrajectory(const std::string& path);
void writeTumTrajectory(const std::string& path, const Trajectory& trajectory);

/// EuRoC-style CSV (e.g. state_groundtruth_estimate0/data.csv): extra columns after qz are ignored.
Trajectory readEurocTrajectory(const std::string& path);
void writeEurocTrajectory(const std::string& path, const Trajectory& trajectory);

}  // namespace ltlo::io
