#include "test_bag_writer.h"

#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

#include "ltlo/io/sequence_reader.h"

namespace ltlo::io::test {
namespace {

ros::Time stamp(double t_s) { return ros::Time(t_s); }

sensor_msgs::Image imageMessage(const cv::Mat& image, const std::string& encoding, double t_s) {
  sensor_msgs::Image message;
  message.header.stamp = stamp(t_s);
  message.header.frame_id = "camera_color_optical_frame";
  message.width = image.cols;
  message.height = image.rows;
  message.encoding = encoding;
  message.is_bigendian = 0;
  message.step = static_cast<uint32_t>(image.cols * image.elemSize());
  message.data.resize(static_cast<size_t>(message.step) * image.rows);
  for (int v = 0; v < image.rows; ++v) {
    std::memcpy(message.data.data() + static_cast<size_t>(v) * message.step, image.ptr(v), message.step);
  }
  return message;
}

sensor_msgs::CompressedImage compressedMessage(const std::vector<uint8_t>& bytes, const std::string& format,
                                               double t_s) {
  sensor_msgs::CompressedImage message;
  message.header.stamp = stamp(t_s);
  message.format = format;
  message.data = bytes;
  return message;
}

std::vector<uint8_t> encode(const std::string& extension, const cv::Mat& image) {
  std::vector<uint8_t> bytes;
  if (!cv::imencode(extension, image, bytes)) throw std::runtime_error("cannot encode " + extension);
  return bytes;
}

sensor_msgs::CameraInfo cameraInfo(const CameraCalib& camera, double t_s) {
  sensor_msgs::CameraInfo info;
  info.header.stamp = stamp(t_s);
  const PinholeCamera& k = camera.camera;
  info.width = k.width();
  info.height = k.height();
  info.K = {k.fx(), 0.0, k.cx(), 0.0, k.fy(), k.cy(), 0.0, 0.0, 1.0};
  const LensDistortion& lens = camera.lens;
  switch (lens.model) {
    case LensModel::kPinhole:
      info.distortion_model = "plumb_bob";
      info.D = {0, 0, 0, 0, 0};
      break;
    case LensModel::kRadTan:
      info.distortion_model = "plumb_bob";
      info.D = {lens.k1, lens.k2, lens.p1, lens.p2, lens.k3};
      break;
    case LensModel::kRational:
      info.distortion_model = "rational_polynomial";
      info.D = {lens.k1, lens.k2, lens.p1, lens.p2, lens.k3, lens.k4, lens.k5, lens.k6};
      break;
    case LensModel::kKannalaBrandt:
      info.distortion_model = "equidistant";
      info.D = {lens.k1, lens.k2, lens.k3, lens.k4};
      break;
  }
  return info;
}

sensor_msgs::Imu imuMessage(double t_s, const Vec3& gyro, const Vec3& acc) {
  sensor_msgs::Imu imu;
  imu.header.stamp = stamp(t_s);
  imu.angular_velocity.x = gyro.x(), imu.angular_velocity.y = gyro.y(), imu.angular_velocity.z = gyro.z();
  imu.linear_acceleration.x = acc.x(), imu.linear_acceleration.y = acc.y(), imu.linear_acceleration.z = acc.z();
  return imu;
}

// The test writer's IMU times (test_sequence_writer.cc's rule) at another rate.
std::vector<double> imuTimes(const TestSequenceSpec& spec, double rate_hz) {
  std::vector<double> times_s;
  const double t_end_s = frameTime(spec, spec.num_frames - 1) + 0.05;
  for (int k = 0;; ++k) {
    const double t_s = spec.t0_s - 0.05 + spec.imu_offset_s + k / rate_hz;
    if (t_s > t_end_s) break;
    times_s.push_back(std::stod(timeText(t_s)));
  }
  return times_s;
}

}  // namespace

void writeTestBag(const std::string& bag_path, const TestBagSpec& spec) {
  const TestSequenceSpec& seq = spec.sequence;
  rosbag::Bag bag(bag_path, rosbag::bagmode::Write);
  const double delay_s = spec.record_delay_s;
  if (spec.with_camera_info) {
    CameraCalib camera = testCalib(seq).camera;
    camera.lens = spec.camera_info_lens;
    bag.write(spec.topics.camera_info, stamp(seq.t0_s + delay_s), cameraInfo(camera, seq.t0_s));
  }
  // IMU first (the bag sorts by record time; the reader must not care either way).
  if (!spec.topics.imu.empty()) {
    for (double t_s : imuTimes(seq, seq.imu_rate_hz)) {
      bag.write(spec.topics.imu, stamp(t_s + delay_s), imuMessage(t_s, testGyro(t_s), testAcc(t_s)));
    }
  } else if (!spec.topics.accel.empty()) {
    for (double t_s : imuTimes(seq, spec.accel_rate_hz)) {
      bag.write(spec.topics.accel, stamp(t_s + delay_s), imuMessage(t_s, Vec3::Zero(), testAcc(t_s)));
    }
    for (double t_s : imuTimes(seq, spec.gyro_rate_hz)) {
      bag.write(spec.topics.gyro, stamp(t_s + delay_s), imuMessage(t_s, testGyro(t_s), Vec3::Zero()));
    }
  }
  for (int k = 0; k < seq.num_frames; ++k) {
    const double t_s = std::stod(timeText(frameTime(seq, k)));
    cv::Mat bgr(seq.height, seq.width, CV_8UC3);
    cv::Mat depth_mm(seq.height, seq.width, CV_16UC1);
    for (int v = 0; v < seq.height; ++v) {
      for (int u = 0; u < seq.width; ++u) {
        const Vec3 c = testColor(u, v, k);
        bgr.at<cv::Vec3b>(v, u) = cv::Vec3b(c.x(), c.y(), c.z());
        depth_mm.at<uint16_t>(v, u) = static_cast<uint16_t>(testDepthRaw(u, v, k));
      }
    }
    const ros::Time record = stamp(t_s + delay_s);
    switch (spec.color) {
      case BagColor::kBgr8:
        bag.write(spec.topics.rgb, record, imageMessage(bgr, "bgr8", t_s));
        break;
      case BagColor::kRgb8: {
        cv::Mat rgb;
        cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
        bag.write(spec.topics.rgb, record, imageMessage(rgb, "rgb8", t_s));
        break;
      }
      case BagColor::kMono8: {
        cv::Mat grey;
        cv::extractChannel(bgr, grey, 0);
        bag.write(spec.topics.rgb, record, imageMessage(grey, "mono8", t_s));
        break;
      }
      case BagColor::kPng:
        bag.write(spec.topics.rgb, record, compressedMessage(encode(".png", bgr), "bgr8; png compressed bgr8", t_s));
        break;
      case BagColor::kJpeg:
        bag.write(spec.topics.rgb, record, compressedMessage(encode(".jpg", bgr), "rgb8; jpeg compressed bgr8", t_s));
        break;
    }
    const double depth_t_s = std::stod(timeText(t_s + seq.depth_offset_s));
    const ros::Time depth_record = stamp(depth_t_s + delay_s);
    switch (spec.depth) {
      case BagDepth::k16UC1:
        bag.write(spec.topics.depth, depth_record, imageMessage(depth_mm, "16UC1", depth_t_s));
        break;
      case BagDepth::k32FC1: {
        cv::Mat depth_m(seq.height, seq.width, CV_32FC1);
        for (int v = 0; v < seq.height; ++v) {
          for (int u = 0; u < seq.width; ++u) {
            depth_m.at<float>(v, u) = spec.nan_diagonal && u == v ? std::numeric_limits<float>::quiet_NaN()
                                                                  : static_cast<float>(testDepthRaw(u, v, k) / 1000.0);
          }
        }
        bag.write(spec.topics.depth, depth_record, imageMessage(depth_m, "32FC1", depth_t_s));
        break;
      }
      case BagDepth::kCompressed16UC1:
      case BagDepth::kCompressed32FC1: {
        const bool metres = spec.depth == BagDepth::kCompressed32FC1;
        cv::Mat png_values = depth_mm;
        if (metres) {
          png_values = cv::Mat(seq.height, seq.width, CV_16UC1);
          for (int v = 0; v < seq.height; ++v) {
            for (int u = 0; u < seq.width; ++u) {
              const float depth = static_cast<float>(testDepthRaw(u, v, k) / 1000.0);
              png_values.at<uint16_t>(v, u) = static_cast<uint16_t>(kTestDepthQuantA / depth + kTestDepthQuantB);
            }
          }
        }
        std::vector<uint8_t> bytes(12);
        const int32_t format = 0;
        std::memcpy(bytes.data(), &format, 4);
        std::memcpy(bytes.data() + 4, &kTestDepthQuantA, 4);
        std::memcpy(bytes.data() + 8, &kTestDepthQuantB, 4);
        const std::vector<uint8_t> png = encode(".png", png_values);
        bytes.insert(bytes.end(), png.begin(), png.end());
        bag.write(spec.topics.depth, depth_record,
                  compressedMessage(bytes, metres ? "32FC1; compressedDepth" : "16UC1; compressedDepth png", depth_t_s));
        break;
      }
    }
  }
  bag.close();
}

void writeBagFromFolder(const std::string& dir, const std::string& bag_path, const BagTopics& topics,
                        bool png_colour, int bad_colour_frame) {
  SequenceReaderOptions options;
  options.read_ground_truth = false;
  const SequenceReader reader = SequenceReader::open(dir, options);
  if (reader.calib().camera.depth_map_factor != 1000.0) {
    throw std::runtime_error(dir + ": writeBagFromFolder needs DepthMapFactor 1000 (16UC1 is millimetres)");
  }
  rosbag::Bag bag(bag_path, rosbag::bagmode::Write);
  // Record times 1 ms after the stamps (a bag refuses record time 0, where simulated sequences start).
  auto record = [](double t_s) { return stamp(t_s + 0.001); };
  const double first_s = reader.frameCount() > 0 ? reader.frameTime(0) : 0.0;
  if (!topics.camera_info.empty()) bag.write(topics.camera_info, record(first_s), cameraInfo(reader.calib().camera, first_s));
  if (!topics.imu.empty()) {
    for (const ImuSample& sample : reader.imu()) {
      bag.write(topics.imu, record(sample.t_s), imuMessage(sample.t_s, sample.gyro_rad_s, sample.acc_m_s2));
    }
  }
  for (int i = 0; i < reader.frameCount(); ++i) {
    const FrameFiles& files = reader.frameFiles(i);
    const cv::Mat color = cv::imread(files.color_path, cv::IMREAD_COLOR);
    const cv::Mat depth = cv::imread(files.depth_path, cv::IMREAD_UNCHANGED);
    if (color.empty() || depth.type() != CV_16UC1) throw std::runtime_error("cannot read frame " + files.color_path);
    if (png_colour) {
      bag.write(topics.rgb, record(files.t_s), compressedMessage(encode(".png", color), "bgr8; png compressed bgr8", files.t_s));
    } else {
      // Frame bad_colour_frame: an encoding the reader does not take (a bag that breaks part-way).
      bag.write(topics.rgb, record(files.t_s), imageMessage(color, i == bad_colour_frame ? "yuv444" : "bgr8", files.t_s));
    }
    bag.write(topics.depth, record(files.depth_t_s), imageMessage(depth, "16UC1", files.depth_t_s));
  }
  bag.close();
}

}  // namespace ltlo::io::test
