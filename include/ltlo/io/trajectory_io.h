#pragma once
/// Trajectory files: TUM ("timestamp tx ty tz qx qy qz qw", seconds) and EuRoC CSV
/// ("timestamp_ns,px,py,pz,qw,qx,qy,qz", nanoseconds). Readers throw InputError naming the file,
/// the line and the value; writers keep full precision (timestamps with 9 decimals).
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
