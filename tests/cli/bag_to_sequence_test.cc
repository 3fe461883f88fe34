// bag_to_sequence (issue 29) as a user runs it: a bag written with rosbag's writer, converted to a
// folder, read back with SequenceReader::open, gives the bag reader's frames, stamps, IMU samples,
// images and calibration; bad input (a missing topic, a non-empty --out, a bad message part-way)
// exits 2 with the reader's message.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <rosbag/bag.h>
#include <sensor_msgs/Image.h>

#include "ltlo/io/sequence_reader.h"
#include "program_runner.h"
#include "test_bag_writer.h"

namespace ltlo::cli_test {
namespace {

namespace fs = std::filesystem;
using io::test::BagColor;
using io::test::BagDepth;
using io::test::TestBagSpec;

class BagToSequence : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    work_ = fs::temp_directory_path() / ("ltlo_bag_to_seq_" + test + "_" + std::to_string(::getpid()));
    fs::remove_all(work_);
    fs::create_directories(work_);
  }
  void TearDown() override { fs::remove_all(work_); }

  ProgramResult convert(const fs::path& bag, const std::vector<std::string>& extra) {
    std::vector<std::string> argv = {programPath("bag_to_sequence"), "--bag", bag.string(), "--out", out().string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return runProgram(argv);
  }
  fs::path out() const { return work_ / "seq"; }

  fs::path work_;
};

void expectSameCalib(const SensorCalib& got, const SensorCalib& expected) {
  const PinholeCamera& a = got.camera.camera;
  const PinholeCamera& b = expected.camera.camera;
  EXPECT_EQ(a.fx(), b.fx());
  EXPECT_EQ(a.fy(), b.fy());
  EXPECT_EQ(a.cx(), b.cx());
  EXPECT_EQ(a.cy(), b.cy());
  EXPECT_EQ(a.width(), b.width());
  EXPECT_EQ(a.height(), b.height());
  const LensDistortion& la = got.camera.lens;
  const LensDistortion& lb = expected.camera.lens;
  EXPECT_EQ(la.model, lb.model);
  const double coefficients_a[] = {la.k1, la.k2, la.k3, la.k4, la.k5, la.k6, la.p1, la.p2};
  const double coefficients_b[] = {lb.k1, lb.k2, lb.k3, lb.k4, lb.k5, lb.k6, lb.p1, lb.p2};
  for (int i = 0; i < 8; ++i) EXPECT_EQ(coefficients_a[i], coefficients_b[i]) << "coefficient " << i;
  EXPECT_EQ(got.camera.depth_map_factor, expected.camera.depth_map_factor);
  EXPECT_EQ(got.camera.fps, expected.camera.fps);
  ASSERT_EQ(got.has_imu, expected.has_imu);
  if (got.has_imu) {
    EXPECT_EQ((got.imu.T_b_c.matrix() - expected.imu.T_b_c.matrix()).norm(), 0.0);
    EXPECT_EQ(got.imu.noise_gyro, expected.imu.noise_gyro);
    EXPECT_EQ(got.imu.acc_walk, expected.imu.acc_walk);
    EXPECT_EQ(got.imu.rate_hz, expected.imu.rate_hz);
    EXPECT_EQ(got.imu.time_offset_s, expected.imu.time_offset_s);
  }
}

int differingBytes(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return -1;
  int rows = 0;
  for (int v = 0; v < a.rows; ++v) rows += std::memcmp(a.ptr(v), b.ptr(v), a.cols * a.elemSize()) != 0;
  return rows;
}

/// The folder read back against the bag: frames, stamps, IMU, colour pixels, depth within the
/// 16-bit quantisation of DepthMapFactor, calibration.
void expectFolderMatchesBag(const io::SequenceReader& bag, const io::SequenceReader& folder) {
  ASSERT_EQ(folder.frameCount(), bag.frameCount());
  const double step_m = 1.0 / bag.calib().camera.depth_map_factor;
  for (int k = 0; k < bag.frameCount(); ++k) {
    EXPECT_EQ(folder.frameTime(k), bag.frameTime(k)) << "frame " << k;
    EXPECT_EQ(folder.frameFiles(k).depth_t_s, bag.frameFiles(k).depth_t_s) << "frame " << k;
    const io::RgbdImuFrame a = bag.load(k);
    const io::RgbdImuFrame b = folder.load(k);
    EXPECT_EQ(differingBytes(b.color_bgr, a.color_bgr), 0) << "frame " << k;
    ASSERT_EQ(b.depth_m.size(), a.depth_m.size());
    double worst_m = 0.0;
    for (int v = 0; v < a.depth_m.rows; ++v) {
      for (int u = 0; u < a.depth_m.cols; ++u) {
        worst_m = std::max(worst_m, std::abs(double(a.depth_m.at<float>(v, u)) - b.depth_m.at<float>(v, u)));
      }
    }
    EXPECT_LE(worst_m, 0.5 * step_m + 1e-6) << "frame " << k;
    // The per-frame IMU cut is the same stream cut at the same stamps.
    ASSERT_EQ(b.imu.size(), a.imu.size()) << "frame " << k;
  }
  ASSERT_EQ(folder.imu().size(), bag.imu().size());
  for (size_t i = 0; i < bag.imu().size(); ++i) {
    ASSERT_EQ(folder.imu()[i].t_s, bag.imu()[i].t_s) << "sample " << i;
    ASSERT_EQ((folder.imu()[i].gyro_rad_s - bag.imu()[i].gyro_rad_s).norm(), 0.0) << "sample " << i;
    ASSERT_EQ((folder.imu()[i].acc_m_s2 - bag.imu()[i].acc_m_s2).norm(), 0.0) << "sample " << i;
  }
  expectSameCalib(folder.calib(), bag.calib());
}

TEST_F(BagToSequence, RawColourAndMillimetreDepthRoundTripExactly) {
  TestBagSpec spec;  // bgr8, 16UC1 mm, realsense: separate accel and gyro topics
  spec.camera_info_lens.model = LensModel::kRadTan;
  spec.camera_info_lens.k1 = -0.05;
  spec.camera_info_lens.k2 = 0.01;
  spec.camera_info_lens.p1 = 0.001;
  spec.camera_info_lens.p2 = -0.002;
  spec.camera_info_lens.k3 = 0.0005;
  const fs::path bag = work_ / "raw.bag";
  io::test::writeTestBag(bag.string(), spec);
  const ProgramResult result = convert(bag, {"--bag-preset", "realsense", "--progress-every", "2"});
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  EXPECT_NE(result.out.find("frames 5\n"), std::string::npos) << result.out;
  EXPECT_NE(result.err.find("frames 2/5"), std::string::npos) << result.err;  // progress line
  EXPECT_NE(result.err.find("fps"), std::string::npos) << result.err;

  const io::SequenceReader from_bag = io::SequenceReader::openBag(bag.string(), spec.topics);
  const io::SequenceReader folder = io::SequenceReader::open(out().string());
  ASSERT_TRUE(from_bag.hasImu());
  expectFolderMatchesBag(from_bag, folder);
  EXPECT_EQ(folder.calib().camera.lens.model, LensModel::kRadTan);
  EXPECT_EQ(folder.calib().camera.lens.k3, 0.0005);
  EXPECT_TRUE(fs::is_regular_file(out() / "associations.txt"));
  // 16UC1 millimetres with DepthMapFactor 1000: the PNG holds the message's values.
  for (int k = 0; k < folder.frameCount(); ++k) {
    const cv::Mat png = cv::imread(folder.frameFiles(k).depth_path, cv::IMREAD_UNCHANGED);
    ASSERT_EQ(png.type(), CV_16UC1);
    for (int v = 0; v < png.rows; ++v) {
      for (int u = 0; u < png.cols; ++u) {
        ASSERT_EQ(png.at<std::uint16_t>(v, u), io::test::testDepthRaw(u, v, k)) << k << " " << u << "," << v;
      }
    }
  }
}

TEST_F(BagToSequence, PngColourWithCalibFileRoundTrips) {
  TestBagSpec spec;
  spec.color = BagColor::kPng;
  spec.topics = io::bagTopicPreset("realsense-unite");
  const fs::path bag = work_ / "png.bag";
  io::test::writeTestBag(bag.string(), spec);
  SensorCalib calib = io::test::testCalib(spec.sequence);
  calib.camera.lens.model = LensModel::kKannalaBrandt;
  calib.camera.lens.k1 = 0.01, calib.camera.lens.k2 = -0.002, calib.camera.lens.k3 = 0.0003, calib.camera.lens.k4 = 1e-5;
  calib.imu.time_offset_s = 0.004;  // imu.txt keeps the IMU's stamps, calib.yaml the offset
  const fs::path calib_path = work_ / "calib_in.yaml";
  calib.write(calib_path.string());
  const ProgramResult result = convert(bag, {"--bag-preset", "realsense-unite", "--calib", calib_path.string()});
  ASSERT_EQ(result.exit_code, 0) << result.describe();

  io::SequenceReaderOptions options;
  options.calib_override = SensorCalib::load(calib_path.string());
  const io::SequenceReader from_bag = io::SequenceReader::openBag(bag.string(), spec.topics, options);
  const io::SequenceReader folder = io::SequenceReader::open(out().string());
  ASSERT_TRUE(folder.calib().has_imu);
  EXPECT_EQ(folder.calib().camera.lens.model, LensModel::kKannalaBrandt);
  expectFolderMatchesBag(from_bag, folder);
}

TEST_F(BagToSequence, MetreDepthIsWithinTheQuantisation) {
  TestBagSpec spec;
  spec.color = BagColor::kRgb8;
  spec.depth = BagDepth::k32FC1;
  spec.nan_diagonal = true;
  spec.topics = io::bagTopicPreset("tum");
  const fs::path bag = work_ / "tum.bag";
  io::test::writeTestBag(bag.string(), spec);
  SensorCalib calib = io::test::testCalib(spec.sequence);
  calib.has_imu = false;
  calib.camera.depth_map_factor = 5000.0;  // TUM's
  const fs::path calib_path = work_ / "calib_tum.yaml";
  calib.write(calib_path.string());
  const ProgramResult result = convert(bag, {"--bag-preset", "tum", "--calib", calib_path.string()});
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  EXPECT_FALSE(fs::exists(out() / "imu.txt"));
  io::SequenceReaderOptions options;
  options.calib_override = calib;
  const io::SequenceReader from_bag = io::SequenceReader::openBag(bag.string(), spec.topics, options);
  const io::SequenceReader folder = io::SequenceReader::open(out().string());
  expectFolderMatchesBag(from_bag, folder);
  EXPECT_EQ(folder.load(0).depth_m.at<float>(3, 3), 0.0f);  // NaN: no reading
}

TEST_F(BagToSequence, MissingTopicExitsTwoWithTheReadersMessage) {
  const fs::path bag = work_ / "small.bag";
  io::test::writeTestBag(bag.string(), TestBagSpec{});
  const ProgramResult result = convert(bag, {"--bag-preset", "tum"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find(bag.string() + ": no topic /camera/rgb/image_color (--rgb-topic); the bag has: "),
            std::string::npos)
      << result.err;
  EXPECT_FALSE(fs::exists(out()));
}

TEST_F(BagToSequence, NonEmptyOutExitsTwoUnlessForced) {
  const fs::path bag = work_ / "small.bag";
  io::test::writeTestBag(bag.string(), TestBagSpec{});
  fs::create_directories(out());
  { std::ofstream(out() / "notes.txt") << "keep\n"; }
  const ProgramResult refused = convert(bag, {"--bag-preset", "realsense"});
  EXPECT_EQ(refused.exit_code, 2) << refused.describe();
  EXPECT_NE(refused.err.find(out().string() + ": --out exists and is not empty (give --force"), std::string::npos)
      << refused.err;
  EXPECT_FALSE(fs::exists(out() / "rgb.txt"));
  const ProgramResult forced = convert(bag, {"--bag-preset", "realsense", "--force"});
  ASSERT_EQ(forced.exit_code, 0) << forced.describe();
  EXPECT_EQ(io::SequenceReader::open(out().string()).frameCount(), 5);
  EXPECT_TRUE(fs::exists(out() / "notes.txt"));  // only the program's own files are replaced
}

TEST_F(BagToSequence, BadMessagePartWayKeepsTheFramesBeforeIt) {
  const fs::path bag = work_ / "bad.bag";
  {
    rosbag::Bag writer(bag.string(), rosbag::bagmode::Write);
    for (int k = 0; k < 4; ++k) {
      sensor_msgs::Image image;
      image.header.stamp = ros::Time(1.0 + 0.1 * k);
      image.width = 16, image.height = 12;
      image.encoding = k == 2 ? "yuv422" : "bgr8";
      image.step = k == 2 ? 32 : 48;
      image.data.assign(image.step * 12, 7);
      writer.write("/rgb", image.header.stamp, image);
      sensor_msgs::Image depth = image;
      depth.encoding = "16UC1", depth.step = 32;
      depth.data.assign(32 * 12, 1);
      writer.write("/depth", image.header.stamp, depth);
    }
  }
  const fs::path calib_path = work_ / "calib.yaml";
  io::test::testCalib(io::test::TestSequenceSpec{}).write(calib_path.string());
  const ProgramResult result =
      convert(bag, {"--rgb-topic", "/rgb", "--depth-topic", "/depth", "--calib", calib_path.string()});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find(bag.string() + ": topic /rgb message 3: unsupported colour encoding 'yuv422'"),
            std::string::npos)
      << result.err;
  EXPECT_NE(result.err.find("stopped after 2 of 4 frames"), std::string::npos) << result.err;
  const io::SequenceReader folder = io::SequenceReader::open(out().string());
  ASSERT_EQ(folder.frameCount(), 2);
  EXPECT_EQ(folder.frameTime(1), 1.1);
  EXPECT_EQ(folder.load(1).color_bgr.at<cv::Vec3b>(0, 0), cv::Vec3b(7, 7, 7));
}

TEST_F(BagToSequence, StampsWithNanosecondsReadBackAsTheSameDoubles) {
  TestBagSpec spec;
  spec.sequence.t0_s = 1403636579.763555584;  // EuRoC-like stamp: more than 6 decimals
  const fs::path bag = work_ / "ns.bag";
  io::test::writeTestBag(bag.string(), spec);
  const ProgramResult result = convert(bag, {"--bag-preset", "realsense"});
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  const io::SequenceReader from_bag = io::SequenceReader::openBag(bag.string(), spec.topics);
  const io::SequenceReader folder = io::SequenceReader::open(out().string());
  ASSERT_EQ(folder.frameCount(), from_bag.frameCount());
  for (int k = 0; k < folder.frameCount(); ++k) EXPECT_EQ(folder.frameTime(k), from_bag.frameTime(k));
}

}  // namespace
}  // namespace ltlo::cli_test
