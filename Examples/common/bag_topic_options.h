#pragma once
// The bag-topic options shared by the programs that read ROS 1 bags (rgbd_inertial, rgbd,
// bag_to_sequence): --bag-preset and one --*-topic per stream, resolved into io::BagTopics.
#include <string>

#include <CLI/CLI.hpp>

#include "ltlo/io/bag_topics.h"

namespace ltlo::examples {

/// What the command line gave; resolve() turns it into the topics the reader takes.
struct BagTopicOptions {
  std::string preset;  ///< --bag-preset (empty: none)
  std::string rgb, depth, imu, accel, gyro, camera_info;

  /// Adds --bag-preset, --rgb-topic, --depth-topic, --imu-topic, --accel-topic, --gyro-topic and
  /// --camera-info-topic to `app`.
  void addTo(CLI::App& app) {
    app.add_option("--bag-preset", preset, "bag topic names: " + io::bagTopicPresetNames());
    app.add_option("--rgb-topic", rgb, "bag: colour topic (sensor_msgs/Image or CompressedImage)");
    app.add_option("--depth-topic", depth, "bag: depth topic (16UC1 mm, 32FC1 m, compressedDepth)");
    app.add_option("--imu-topic", imu, "bag: sensor_msgs/Imu topic");
    app.add_option("--accel-topic", accel, "bag: accelerometer topic (with --gyro-topic)");
    app.add_option("--gyro-topic", gyro, "bag: gyroscope topic (with --accel-topic)");
    app.add_option("--camera-info-topic", camera_info, "bag: sensor_msgs/CameraInfo of the colour camera");
  }

  /// The preset's topics (none without a preset), each --*-topic given replacing one; a united
  /// --imu-topic replaces the preset's accel/gyro pair and the other way round. Throws InputError
  /// for an unknown preset.
  io::BagTopics resolve() const {
    io::BagTopics topics = preset.empty() ? io::BagTopics{} : io::bagTopicPreset(preset);
    const std::pair<const std::string*, std::string*> given_topics[] = {
        {&rgb, &topics.rgb},     {&depth, &topics.depth}, {&imu, &topics.imu},
        {&accel, &topics.accel}, {&gyro, &topics.gyro},   {&camera_info, &topics.camera_info}};
    for (const auto& [given, topic] : given_topics) {
      if (!given->empty()) *topic = *given;
    }
    // One IMU source: a united topic given on the command line replaces the preset's pair, and back.
    if (!imu.empty()) topics.accel.clear(), topics.gyro.clear();
    if (!accel.empty() || !gyro.empty()) topics.imu.clear();
    return topics;
  }
};

}  // namespace ltlo::examples
