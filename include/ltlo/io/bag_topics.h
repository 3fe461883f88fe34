#pragma once
/// ROS 1 bags as sequences: which topics hold the colour, depth, IMU and CameraInfo messages,
/// the presets of the layouts people record, and a bag's table of contents (--list-topics).
/// SequenceReader::openBag reads a bag through these (sequence_reader.h).
#include <string>
#include <vector>

namespace ltlo::io {

/// Topic names of one bag; an empty name = not read. Either `imu` (sensor_msgs/Imu) or both
/// `accel` and `gyro` (sensor_msgs/Imu with only linear_acceleration, resp. angular_velocity
/// filled, as the RealSense driver publishes them without unite_imu) give the IMU.
struct BagTopics {
  std::string rgb;          ///< sensor_msgs/Image or sensor_msgs/CompressedImage (colour)
  std::string depth;        ///< sensor_msgs/Image (16UC1 mm, 32FC1 m) or CompressedImage (compressedDepth)
  std::string imu;          ///< sensor_msgs/Imu, both sensors in one message
  std::string accel;        ///< sensor_msgs/Imu, accelerometer only
  std::string gyro;         ///< sensor_msgs/Imu, gyroscope only
  std::string camera_info;  ///< sensor_msgs/CameraInfo of the colour camera (first message used)
};

/// "tum" (TUM RGB-D benchmark bags), "realsense" (realsense2_camera with align_depth, separate
/// accel/gyro topics), "realsense-unite" (the same with unite_imu_method: /camera/imu),
/// "openloris" (OpenLORIS-Scene's d400 topics); throws InputError naming the presets otherwise.
BagTopics bagTopicPreset(const std::string& name);
/// The preset names, for help texts: "tum, realsense, realsense-unite, openloris".
std::string bagTopicPresetNames();

/// One topic of a bag's index (no message is read).
struct BagTopicInfo {
  std::string topic;
  std::string type;        ///< e.g. "sensor_msgs/Image"
  long count = 0;          ///< messages
  double begin_s = 0.0;    ///< first and last record time (the bag's, not the header stamps)
  double end_s = 0.0;
  double rate_hz = 0.0;    ///< (count - 1) / (end_s - begin_s); 0 for fewer than two messages
};

/// The topics of `bag_path` sorted by name; throws InputError (unreadable, truncated or
/// unindexed bag, or a build without bag support).
std::vector<BagTopicInfo> listBagTopics(const std::string& bag_path);
/// One line per topic, "topic  type  count  rate_hz" aligned (what --list-topics prints).
std::string formatBagTopics(const std::vector<BagTopicInfo>& topics);

/// False when ltlo_io was built without rosbag_storage (LTLO_WITH_ROSBAG): every bag function
/// then throws InputError.
bool bagSupportCompiled();

}  // namespace ltlo::io
