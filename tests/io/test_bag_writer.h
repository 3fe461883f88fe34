#pragma once
// Writes small ROS 1 bags with rosbag_storage's writer for the bag reader tests: the test
// sequence's known signals (test_sequence_writer.h) in every message encoding the reader takes,
// and any folder sequence converted message by message (for folder-vs-bag comparisons).
#include <string>

#include "ltlo/io/bag_topics.h"
#include "test_sequence_writer.h"

namespace ltlo::io::test {

enum class BagColor { kRgb8, kBgr8, kMono8, kPng, kJpeg };
enum class BagDepth { k16UC1, k32FC1, kCompressed16UC1, kCompressed32FC1 };

/// Inverse-depth quantisation of the 32FC1 compressedDepth messages written (image_transport's
/// defaults): value = A / depth_m + B.
constexpr float kTestDepthQuantA = 100.0f;
constexpr float kTestDepthQuantB = 10.0f;

struct TestBagSpec {
  TestSequenceSpec sequence;
  BagTopics topics = bagTopicPreset("realsense");  ///< names written (imu, or accel + gyro)
  BagColor color = BagColor::kBgr8;
  BagDepth depth = BagDepth::k16UC1;
  double accel_rate_hz = 62.5;  ///< separate topics: the accelerometer's rate
  double gyro_rate_hz = 200.0;  ///< ... and the gyroscope's (united /imu: sequence.imu_rate_hz)
  bool with_camera_info = true; ///< CameraInfo of testCalib() with camera_info_lens below
  LensDistortion camera_info_lens;
  /// Record time = header stamp + this (a slow recorder): the reader must use the header stamps.
  double record_delay_s = 0.04;
  /// 32FC1 only: pixels (u, v) with u == v get NaN (no reading, as TUM bags have).
  bool nan_diagonal = false;
};

/// Writes the bag; frame k's colour is testColor (grey = its first channel for mono8), depth is
/// testDepthRaw millimetres, the IMU testGyro/testAcc.
void writeTestBag(const std::string& bag_path, const TestBagSpec& spec);

/// The sequence folder `dir` (DATA_FORMAT.md) as a bag: every frame's colour (bgr8, or PNG
/// compressed when `png_colour`) and its 16-bit depth PNG values as 16UC1 (DepthMapFactor must be
/// 1000), the IMU as one Imu topic, CameraInfo from calib.yaml; stamps are the index's times.
/// Frame `bad_colour_frame` (>= 0, raw colour only) gets the unsupported encoding "yuv444".
void writeBagFromFolder(const std::string& dir, const std::string& bag_path, const BagTopics& topics,
                        bool png_colour, int bad_colour_frame = -1);

}  // namespace ltlo::io::test
