#pragma once
// Writes tiny sequences (a few frames of 16x12 pixels) into a temporary folder for the io tests,
// in the DATA_FORMAT.md or OpenLORIS-Scene layout, with content that is a known function of
// pixel, frame and time so readers can be checked value by value.
#include <string>

#include "ltlo/core/calib.h"
#include "ltlo/core/eigen_types.h"

namespace ltlo::io::test {

/// A fresh folder under the system temp dir, removed with its contents on destruction.
class TempDir {
 public:
  explicit TempDir(const std::string& name);
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }
  std::string file(const std::string& relative) const { return path_ + "/" + relative; }

 private:
  std::string path_;
};

struct TestSequenceSpec {
  int num_frames = 5;
  int width = 16;
  int height = 12;
  double fps = 10.0;
  double t0_s = 1.0;            ///< first frame time
  double depth_offset_s = 0.0;  ///< depth timestamps = colour + offset (rgb.txt/depth.txt only)
  double imu_rate_hz = 100.0;
  double imu_offset_s = 0.003;    ///< IMU times = t0 - 0.05 + offset + k / rate: never on a frame
  bool with_associations = true;  ///< associations.txt (else only rgb.txt + depth.txt)
  bool with_imu = true;           ///< imu.txt and IMU keys in calib.yaml
  bool with_calib = true;
  bool with_groundtruth = true;
  bool with_masks = false;
};

/// Calibration the writer uses (fx = fy = 20, centre of the image, DepthMapFactor 1000).
SensorCalib testCalib(const TestSequenceSpec& spec);

/// Frame k's timestamp, and its text as used in file names ("%.6f").
double frameTime(const TestSequenceSpec& spec, int k);
std::string timeText(double t_s);

/// Known signals: linear in time, so linear interpolation reproduces them exactly.
Vec3 testGyro(double t_s);
Vec3 testAcc(double t_s);
/// Raw 16-bit depth value at pixel (u, v) of frame k, and the colour (B, G, R).
int testDepthRaw(int u, int v, int k);
Vec3 testColor(int u, int v, int k);

/// Writes SEQ in the DATA_FORMAT.md layout.
void writeDataFormatSequence(const std::string& dir, const TestSequenceSpec& spec);

/// Writes SEQ in the OpenLORIS layout (color/, aligned_depth/, color.txt, aligned_depth.txt,
/// accel.txt at accel_rate_hz, gyro.txt at gyro_rate_hz, groundtruth.txt; no calib.yaml).
void writeOpenLorisSequence(const std::string& dir, const TestSequenceSpec& spec,
                            double accel_rate_hz, double gyro_rate_hz);

/// Writes imu0/data.csv (EuRoC, nanoseconds) with the test signals and removes imu.txt.
void writeEurocImu(const std::string& dir, const TestSequenceSpec& spec);

/// Whole-file text helpers for injecting faults.
void writeText(const std::string& path, const std::string& text);
std::string readText(const std::string& path);
/// Replaces 1-based line `line_number` of the file.
void replaceLine(const std::string& path, int line_number, const std::string& text);

}  // namespace ltlo::io::test
