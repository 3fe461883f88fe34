// The ROS 1 bag reader (SequenceReader::openBag) against bags the test writes with rosbag's own
// writer: every encoding decoded against the known image, IMU topics, CameraInfo, the folder
// path's numbers, and the bad-bag messages.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <opencv2/core.hpp>
#include <rosbag/bag.h>
#include <set>
#include <thread>

#include "bag_messages.h"
#include "expect_input_error.h"
#include "common/log_capture.h"
#include "ltlo/io/sequence_reader.h"
#include "test_bag_writer.h"

namespace ltlo::io {
namespace {

using test::BagColor;
using test::BagDepth;
using test::TempDir;
using test::TestBagSpec;

// 0 when the Mats have the same size, type and bytes.
int differingValues(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return -1;
  int count = 0;
  for (int v = 0; v < a.rows; ++v) {
    count += std::memcmp(a.ptr(v), b.ptr(v), a.cols * a.elemSize()) != 0;
  }
  return count;
}

void expectKnownColour(const RgbdImuFrame& frame, int k, bool grey, int tolerance) {
  int worst = 0;
  for (int v = 0; v < frame.color_bgr.rows; ++v) {
    for (int u = 0; u < frame.color_bgr.cols; ++u) {
      const Vec3 c = test::testColor(u, v, k);
      const cv::Vec3b got = frame.color_bgr.at<cv::Vec3b>(v, u);
      for (int ch = 0; ch < 3; ++ch) worst = std::max(worst, std::abs(got[ch] - static_cast<int>(grey ? c.x() : c(ch))));
    }
  }
  EXPECT_LE(worst, tolerance) << "frame " << k;
}

// Millimetre messages are converted as the folder reader converts a DepthMapFactor-1000 PNG
// (cv::convertTo by 1/1000, which may differ from raw / 1000.0 in the last bit); metre messages
// carry the float written.
float folderDepth(int raw) {
  cv::Mat depth_m;
  cv::Mat(1, 1, CV_16UC1, cv::Scalar(raw)).convertTo(depth_m, CV_32F, 1.0 / 1000.0);
  return depth_m.at<float>(0, 0);
}

void expectKnownDepth(const RgbdImuFrame& frame, int k, bool nan_diagonal, bool millimetres = true) {
  for (int v = 0; v < frame.depth_m.rows; ++v) {
    for (int u = 0; u < frame.depth_m.cols; ++u) {
      const int raw = test::testDepthRaw(u, v, k);
      const float expected = nan_diagonal && u == v ? 0.0f
                             : millimetres          ? folderDepth(raw)
                                                    : static_cast<float>(raw / 1000.0);
      ASSERT_EQ(frame.depth_m.at<float>(v, u), expected) << "frame " << k << " pixel " << u << "," << v;
    }
  }
}

SequenceReader openTestBag(const std::string& path, const TestBagSpec& spec, SequenceReaderOptions options = {}) {
  test::writeTestBag(path, spec);
  return SequenceReader::openBag(path, spec.topics, options);
}

TEST(BagReader, RawBagHasTheFolderFramesBitForBit) {
  TempDir dir("ltlo_bag_folder");
  test::TestSequenceSpec spec;
  spec.num_frames = 6;
  test::writeDataFormatSequence(dir.file("seq"), spec);
  BagTopics topics = bagTopicPreset("realsense-unite");
  test::writeBagFromFolder(dir.file("seq"), dir.file("seq.bag"), topics, /*png_colour=*/false);
  SequenceReaderOptions options;
  options.read_ground_truth = false;
  const SequenceReader folder = SequenceReader::open(dir.file("seq"), options);
  const SequenceReader bag = SequenceReader::openBag(dir.file("seq.bag"), topics, options);
  ASSERT_TRUE(bag.isBag());
  ASSERT_EQ(bag.frameCount(), 6);
  ASSERT_EQ(folder.frameCount(), 6);
  ASSERT_EQ(bag.imu().size(), folder.imu().size());
  for (size_t i = 0; i < folder.imu().size(); ++i) {
    EXPECT_EQ(bag.imu()[i].t_s, folder.imu()[i].t_s);
    EXPECT_EQ(bag.imu()[i].gyro_rad_s, folder.imu()[i].gyro_rad_s);
    EXPECT_EQ(bag.imu()[i].acc_m_s2, folder.imu()[i].acc_m_s2);
  }
  for (int i = 0; i < 6; ++i) {
    const RgbdImuFrame a = folder.load(i);
    const RgbdImuFrame b = bag.load(i);
    EXPECT_EQ(b.t_s, a.t_s);  // bit-identical stamps, not just close
    EXPECT_EQ(b.depth_t_s, a.depth_t_s);
    EXPECT_EQ(differingValues(a.color_bgr, b.color_bgr), 0) << "colour of frame " << i;
    EXPECT_EQ(differingValues(a.depth_m, b.depth_m), 0) << "depth of frame " << i;
    ASSERT_EQ(a.imu.size(), b.imu.size());
    for (size_t s = 0; s < a.imu.size(); ++s) EXPECT_EQ(a.imu[s].t_s, b.imu[s].t_s);
  }
  // CameraInfo written from calib.yaml comes back as the same camera.
  EXPECT_TRUE(detail::sameCamera(bag.calib().camera, folder.calib().camera));
}

TEST(BagReader, TumLayoutRgb8With32FC1MetresAndNaNHoles) {
  TempDir dir("ltlo_bag_tum");
  TestBagSpec spec;
  spec.topics = bagTopicPreset("tum");
  spec.color = BagColor::kRgb8;
  spec.depth = BagDepth::k32FC1;
  spec.nan_diagonal = true;
  const SequenceReader reader = openTestBag(dir.file("tum.bag"), spec);
  ASSERT_EQ(reader.frameCount(), spec.sequence.num_frames);
  EXPECT_FALSE(reader.hasImu());
  EXPECT_FALSE(reader.calib().has_imu);  // CameraInfo alone: the camera only
  for (int k = 0; k < reader.frameCount(); ++k) {
    const RgbdImuFrame frame = reader.load(k);
    EXPECT_EQ(frame.t_s, std::stod(test::timeText(test::frameTime(spec.sequence, k))));  // header, not record time
    expectKnownColour(frame, k, false, 0);
    expectKnownDepth(frame, k, /*nan_diagonal=*/true, /*millimetres=*/false);
  }
}

TEST(BagReader, RealSenseLayoutMergesSeparateAccelAndGyroTopics) {
  TempDir dir("ltlo_bag_rs");
  TestBagSpec spec;  // realsense preset: bgr8, 16UC1, accel 62.5 Hz, gyro 200 Hz
  const SequenceReader reader = openTestBag(dir.file("rs.bag"), spec);
  ASSERT_EQ(reader.frameCount(), spec.sequence.num_frames);
  ASSERT_TRUE(reader.hasImu());
  // Merged at the union of both stamps inside the span both cover; the signals are linear in time
  // so the interpolated values are exact (to rounding).
  const std::vector<ImuSample>& imu = reader.imu();
  // Expected stamps: both streams' (the writer's rule) inside the span both cover.
  std::set<double> stamps_s;
  const double first_s = spec.sequence.t0_s - 0.05 + spec.sequence.imu_offset_s;
  const double end_s = test::frameTime(spec.sequence, spec.sequence.num_frames - 1) + 0.05;
  double last_accel_s = first_s, last_gyro_s = first_s;
  for (int k = 0; first_s + k / spec.accel_rate_hz <= end_s; ++k) last_accel_s = first_s + k / spec.accel_rate_hz;
  for (int k = 0; first_s + k / spec.gyro_rate_hz <= end_s; ++k) last_gyro_s = first_s + k / spec.gyro_rate_hz;
  for (double rate_hz : {spec.accel_rate_hz, spec.gyro_rate_hz}) {
    for (int k = 0; first_s + k / rate_hz <= std::min(last_accel_s, last_gyro_s) + 1e-9; ++k) {
      stamps_s.insert(std::stod(test::timeText(first_s + k / rate_hz)));
    }
  }
  EXPECT_EQ(imu.size(), stamps_s.size());
  double worst = 0.0;
  for (size_t i = 0; i < imu.size(); ++i) {
    if (i > 0) {
      EXPECT_GT(imu[i].t_s, imu[i - 1].t_s);
    }
    worst = std::max(worst, (imu[i].gyro_rad_s - test::testGyro(imu[i].t_s)).norm());
    worst = std::max(worst, (imu[i].acc_m_s2 - test::testAcc(imu[i].t_s)).norm());
  }
  EXPECT_LT(worst, 1e-9);
  for (int k = 0; k < reader.frameCount(); ++k) {
    const RgbdImuFrame frame = reader.load(k);
    expectKnownColour(frame, k, false, 0);
    expectKnownDepth(frame, k, false);
    EXPECT_FALSE(frame.imu.empty());
  }
}

TEST(BagReader, UnitedImuTopicGivesTheWrittenSamples) {
  TempDir dir("ltlo_bag_unite");
  TestBagSpec spec;
  spec.topics = bagTopicPreset("realsense-unite");
  const SequenceReader reader = openTestBag(dir.file("u.bag"), spec);
  ASSERT_TRUE(reader.hasImu());
  for (const ImuSample& sample : reader.imu()) {
    EXPECT_EQ(sample.gyro_rad_s, test::testGyro(sample.t_s));
    EXPECT_EQ(sample.acc_m_s2, test::testAcc(sample.t_s));
  }
  // 100 Hz from t0 - 0.05 + 0.003 to the last frame + 0.05: 4 frames at 10 Hz = 0.4 s + 0.1 s.
  EXPECT_EQ(reader.imu().size(), 50u);
}

TEST(BagReader, EveryColourEncodingDecodesToTheKnownImage) {
  const std::vector<std::pair<BagColor, int>> cases = {
      {BagColor::kBgr8, 0}, {BagColor::kRgb8, 0}, {BagColor::kMono8, 0}, {BagColor::kPng, 0}, {BagColor::kJpeg, 40}};
  for (const auto& [color, tolerance] : cases) {
    TempDir dir("ltlo_bag_colour");
    TestBagSpec spec;
    spec.color = color;
    const SequenceReader reader = openTestBag(dir.file("c.bag"), spec);
    for (int k = 0; k < reader.frameCount(); ++k) {
      expectKnownColour(reader.load(k), k, color == BagColor::kMono8, tolerance);
    }
  }
}

TEST(BagReader, CompressedDepthBothEncodings) {
  {
    TempDir dir("ltlo_bag_cd16");
    TestBagSpec spec;
    spec.depth = BagDepth::kCompressed16UC1;
    const SequenceReader reader = openTestBag(dir.file("d.bag"), spec);
    for (int k = 0; k < reader.frameCount(); ++k) expectKnownDepth(reader.load(k), k, false);
  }
  TempDir dir("ltlo_bag_cd32");
  TestBagSpec spec;
  spec.depth = BagDepth::kCompressed32FC1;
  const SequenceReader reader = openTestBag(dir.file("d.bag"), spec);
  for (int k = 0; k < reader.frameCount(); ++k) {
    const RgbdImuFrame frame = reader.load(k);
    for (int v = 0; v < frame.depth_m.rows; ++v) {
      for (int u = 0; u < frame.depth_m.cols; ++u) {
        const double depth = test::testDepthRaw(u, v, k) / 1000.0;
        // Quantised inverse depth, truncated as image_transport does: q in (A/d + B - 1, A/d + B],
        // so A / (q - B) lies in [d, d A / (A - d)): below d^2 / (A - d) too far.
        const double error_m = frame.depth_m.at<float>(v, u) - depth;
        EXPECT_GT(error_m, -1e-5);
        EXPECT_LT(error_m, depth * depth / (test::kTestDepthQuantA - depth) + 1e-5);
      }
    }
  }
}

TEST(BagReader, CompressedDepthHeaderIsParsed) {
  uint8_t bytes[16] = {};
  const int32_t format = 0;
  const float a = 100.0f, b = 10.0f;
  std::memcpy(bytes, &format, 4);
  std::memcpy(bytes + 4, &a, 4);
  std::memcpy(bytes + 8, &b, 4);
  const detail::CompressedDepthHeader header = detail::parseCompressedDepthHeader(bytes, 16, "m");
  EXPECT_EQ(header.format, 0);
  EXPECT_EQ(header.quant_a, 100.0f);
  EXPECT_EQ(header.quant_b, 10.0f);
  const std::string error = ltlo::test::inputErrorOf([&] { detail::parseCompressedDepthHeader(bytes, 12, "x.bag: topic /d message 3"); });
  LTLO_EXPECT_CONTAINS(error, "x.bag: topic /d message 3: compressedDepth data of 12 bytes");
}

TEST(BagReader, StampSecondsEqualsParsingTheDecimalText) {
  EXPECT_EQ(detail::stampSeconds(1, 100000000), std::stod("1.100000"));
  EXPECT_EQ(detail::stampSeconds(1403636579, 763555584), std::stod("1403636579.763555584"));
}

TEST(BagReader, CameraInfoDistortionReachesTheCameraModel) {
  TempDir dir("ltlo_bag_lens");
  TestBagSpec spec;
  spec.camera_info_lens.model = LensModel::kRadTan;
  spec.camera_info_lens.k1 = -0.05;
  spec.camera_info_lens.k2 = 0.01;
  spec.camera_info_lens.p1 = 0.001;
  spec.camera_info_lens.p2 = -0.002;
  const SequenceReader reader = openTestBag(dir.file("l.bag"), spec);
  const CameraModel model = reader.calib().camera.model();
  EXPECT_TRUE(model.isDistorted());
  EXPECT_EQ(model.lens().model, LensModel::kRadTan);
  EXPECT_EQ(model.lens().k1, -0.05);
  EXPECT_EQ(model.lens().p2, -0.002);
  EXPECT_EQ(model.pinhole().fx(), 20.0);
  EXPECT_EQ(model.pinhole().width(), spec.sequence.width);
}

TEST(BagReader, CalibrationConflictIsOneWarningNamingBothValues) {
  TempDir dir("ltlo_bag_conflict");
  TestBagSpec spec;
  test::writeTestBag(dir.file("c.bag"), spec);
  SensorCalib given = test::testCalib(spec.sequence);
  given.camera.camera = PinholeCamera(21.5, 20.0, given.camera.camera.cx(), given.camera.camera.cy(),
                                      spec.sequence.width, spec.sequence.height);
  SequenceReaderOptions options;
  options.calib_override = given;
  options.calib_override_source = "calib.yaml";
  ltlo::test::LogCapture capture(log::Level::kWarn);
  const SequenceReader reader = SequenceReader::openBag(dir.file("c.bag"), spec.topics, options);
  EXPECT_EQ(reader.calib().camera.camera.fx(), 21.5);  // the file wins
  int warnings = 0;
  for (const std::string& line : capture.lines()) {
    if (line.find("CameraInfo") == std::string::npos) continue;
    ++warnings;
    LTLO_EXPECT_CONTAINS(line, "fx=20 ");
    LTLO_EXPECT_CONTAINS(line, "fx=21.5 ");
    LTLO_EXPECT_CONTAINS(line, "using calib.yaml");
  }
  EXPECT_EQ(warnings, 1);
  options.prefer_camera_info = true;
  EXPECT_EQ(SequenceReader::openBag(dir.file("c.bag"), spec.topics, options).calib().camera.camera.fx(), 20.0);
}

TEST(BagReader, MissingTopicListsTheBagsTopics) {
  TempDir dir("ltlo_bag_missing");
  TestBagSpec spec;
  test::writeTestBag(dir.file("m.bag"), spec);
  BagTopics topics = spec.topics;
  topics.depth = "/camera/depth/image_rect_raw";
  const std::string error = ltlo::test::inputErrorOf([&] { SequenceReader::openBag(dir.file("m.bag"), topics); });
  LTLO_EXPECT_CONTAINS(error, dir.file("m.bag") + ": no topic /camera/depth/image_rect_raw (--depth-topic)");
  LTLO_EXPECT_CONTAINS(error, "/camera/aligned_depth_to_color/image_raw (sensor_msgs/Image, 5 messages)");
  LTLO_EXPECT_CONTAINS(error, "/camera/gyro/sample (sensor_msgs/Imu");
}

TEST(BagReader, UnsupportedEncodingNamesTopicMessageAndValue) {
  TempDir dir("ltlo_bag_enc");
  {
    rosbag::Bag bag(dir.file("e.bag"), rosbag::bagmode::Write);
    sensor_msgs::CameraInfo info;
    for (int k = 0; k < 3; ++k) {
      sensor_msgs::Image image;
      image.header.stamp = ros::Time(1.0 + 0.1 * k);
      image.width = 16, image.height = 12, image.step = 32;
      image.encoding = k == 2 ? "yuv422" : "bgr8";
      if (k != 2) image.step = 48;
      image.data.assign(image.step * 12, 7);
      bag.write("/rgb", image.header.stamp, image);
      sensor_msgs::Image depth = image;
      depth.encoding = "16UC1", depth.step = 32;
      depth.data.assign(32 * 12, 1);
      bag.write("/depth", image.header.stamp, depth);
    }
  }
  SequenceReaderOptions options;
  options.calib_override = test::testCalib(test::TestSequenceSpec{});
  BagTopics topics;
  topics.rgb = "/rgb", topics.depth = "/depth";
  const SequenceReader reader = SequenceReader::openBag(dir.file("e.bag"), topics, options);
  ASSERT_EQ(reader.frameCount(), 3);
  EXPECT_NO_THROW(reader.load(1));
  const std::string error = ltlo::test::inputErrorOf([&] { reader.load(2); });
  LTLO_EXPECT_CONTAINS(error, dir.file("e.bag") + ": topic /rgb message 3: unsupported colour encoding 'yuv422'");
}

TEST(BagReader, ImageSizeDifferentFromTheCalibrationIsAnError) {
  TempDir dir("ltlo_bag_size");
  TestBagSpec spec;
  test::writeTestBag(dir.file("s.bag"), spec);
  test::TestSequenceSpec other = spec.sequence;
  other.width = 20;
  SequenceReaderOptions options;
  options.calib_override = test::testCalib(other);
  options.calib_override_source = "my_calib.yaml";
  const SequenceReader reader = SequenceReader::openBag(dir.file("s.bag"), spec.topics, options);
  const std::string error = ltlo::test::inputErrorOf([&] { reader.load(0); });
  LTLO_EXPECT_CONTAINS(error, "topic /camera/color/image_raw message 1: size 16x12 differs from the calibrated "
                              "image size 20x12 (my_calib.yaml)");
}

TEST(BagReader, TruncatedBagIsAnInputErrorWithTheReindexHint) {
  TempDir dir("ltlo_bag_trunc");
  TestBagSpec spec;
  test::writeTestBag(dir.file("t.bag"), spec);
  const auto size = std::filesystem::file_size(dir.file("t.bag"));
  std::filesystem::resize_file(dir.file("t.bag"), size / 2);
  const std::string error = ltlo::test::inputErrorOf([&] { SequenceReader::openBag(dir.file("t.bag"), spec.topics); });
  LTLO_EXPECT_CONTAINS(error, dir.file("t.bag") + ": ");
  LTLO_EXPECT_CONTAINS(error, "rosbag reindex " + dir.file("t.bag"));
  const std::string missing = ltlo::test::inputErrorOf([&] { listBagTopics(dir.file("none.bag")); });
  LTLO_EXPECT_CONTAINS(missing, "none.bag: bag file does not exist");
}

TEST(BagReader, ListTopicsCountsAndRates) {
  TempDir dir("ltlo_bag_list");
  TestBagSpec spec;
  test::writeTestBag(dir.file("l.bag"), spec);
  const std::vector<BagTopicInfo> topics = listBagTopics(dir.file("l.bag"));
  ASSERT_EQ(topics.size(), 5u);  // sorted by name
  EXPECT_EQ(topics[0].topic, "/camera/accel/sample");
  EXPECT_EQ(topics[1].topic, "/camera/aligned_depth_to_color/image_raw");
  EXPECT_EQ(topics[1].count, 5);
  EXPECT_NEAR(topics[1].rate_hz, 10.0, 1e-6);
  EXPECT_EQ(topics[2].type, "sensor_msgs/CameraInfo");
  EXPECT_EQ(topics[4].topic, "/camera/gyro/sample");
  EXPECT_NEAR(topics[4].rate_hz, 200.0, 1e-3);
  const std::string table = formatBagTopics(topics);
  LTLO_EXPECT_CONTAINS(table, "sensor_msgs/Imu");
}

TEST(BagReader, ConcurrentLoadsGiveTheSameFramesAsSequentialOnes) {
  TempDir dir("ltlo_bag_threads");
  TestBagSpec spec;
  spec.sequence.num_frames = 12;
  const SequenceReader reader = openTestBag(dir.file("p.bag"), spec);
  std::vector<RgbdImuFrame> frames(12);
  std::vector<std::thread> threads;
  for (int t = 0; t < 3; ++t) {
    threads.emplace_back([&, t] {
      for (int i = t; i < 12; i += 3) frames[i] = reader.load(i);
    });
  }
  for (std::thread& thread : threads) thread.join();
  for (int i = 0; i < 12; ++i) {
    const RgbdImuFrame again = reader.load(i);
    EXPECT_EQ(differingValues(frames[i].color_bgr, again.color_bgr), 0);
    EXPECT_EQ(differingValues(frames[i].depth_m, again.depth_m), 0);
  }
}

}  // namespace
}  // namespace ltlo::io
