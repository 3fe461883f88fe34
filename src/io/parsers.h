#pragma once
// The text readers of ltlo_io on streams (private to ltlo_io; the public functions open the file
// and call these; the fuzz targets in tests/fuzz call them on memory). `path` names the file in
// messages; every failure throws InputError "<path>:<line>: <what> ('<value>')".
#include <istream>
#include <string>
#include <vector>

#include "ltlo/core/sequence_options.h"
#include "ltlo/io/imu_io.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/io/trajectory_io.h"

namespace ltlo::io::detail {

/// One line of rgb.txt / depth.txt / color.txt: "timestamp path".
struct ListedImage {
  double t_s = 0.0;
  std::string path;  ///< joined with the sequence folder
  int line = 0;
};

/// rgb.txt / depth.txt / color.txt / aligned_depth.txt: "timestamp path" per line, strictly
/// increasing timestamps; '#' comments and blank lines skipped. Image existence is not checked.
std::vector<ListedImage> parseImageList(std::istream& in, const std::string& dir,
                                        const std::string& list_path);

/// associations.txt: "t_rgb rgb_path t_depth depth_path" per line, colour times strictly
/// increasing. Image existence is not checked.
std::vector<FrameFiles> parseAssociations(std::istream& in, const std::string& dir,
                                          const std::string& list_path);

/// imu.txt ("t gx gy gz ax ay az", s; half rows allowed) and EuRoC imu0/data.csv
/// ("t_ns,wx,wy,wz,ax,ay,az"), as readImuText and readEurocImuCsv.
ImuSamples parseImuText(std::istream& in, const std::string& path, const SequenceOptions& options);
ImuSamples parseEurocImuCsv(std::istream& in, const std::string& path,
                            const SequenceOptions& options);
/// OpenLORIS accel.txt and gyro.txt ("t x y z", s), merged as readOpenLorisImu does.
ImuSamples parseOpenLorisImu(std::istream& accel_in, const std::string& accel_path,
                             std::istream& gyro_in, const std::string& gyro_path,
                             const SequenceOptions& options);

/// TUM and EuRoC trajectories (quaternions normalised, one warning per file when not unit).
Trajectory parseTumTrajectory(std::istream& in, const std::string& path);
Trajectory parseEurocTrajectory(std::istream& in, const std::string& path);

}  // namespace ltlo::io::detail
