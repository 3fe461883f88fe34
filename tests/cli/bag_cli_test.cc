// rgbd_inertial --bag (issue 29) as a user runs it: --list-topics, a missing topic, a truncated
// bag, and a generated sequence run from its folder and from a bag of it (written with rosbag's
// writer) giving byte-identical trajectory.txt files (--single-thread) and, with --groundtruth,
// the same ATE.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "program_runner.h"
#include "test_bag_writer.h"

namespace ltlo::cli_test {
namespace {

namespace fs = std::filesystem;

std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

class BagCli : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    work_ = fs::temp_directory_path() / ("ltlo_bag_cli_" + test + "_" + std::to_string(::getpid()));
    fs::remove_all(work_);
    fs::create_directories(work_);
  }
  void TearDown() override { fs::remove_all(work_); }

  /// The io tests' small bag (16x12, realsense preset, separate accel/gyro topics).
  fs::path smallBag() {
    const fs::path bag = work_ / "small.bag";
    io::test::TestBagSpec spec;
    io::test::writeTestBag(bag.string(), spec);
    return bag;
  }

  ProgramResult slamOnBag(const fs::path& bag, const std::vector<std::string>& extra) {
    std::vector<std::string> argv = {programPath("rgbd_inertial"), "--settings", settings_, "--bag", bag.string(),
                                     "--out", (work_ / "run").string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return runProgram(argv);
  }

  fs::path work_;
  std::string settings_ = sourceDir() + "/config_yaml/synthetic.yaml";
};

TEST_F(BagCli, ListTopicsPrintsTypesCountsAndRates) {
  const fs::path bag = smallBag();
  const ProgramResult result = runProgram({programPath("rgbd_inertial"), "--bag", bag.string(), "--list-topics"});
  ASSERT_EQ(result.exit_code, 0) << result.describe();
  EXPECT_NE(result.out.find("/camera/color/image_raw"), std::string::npos) << result.out;
  // 5 frames at 10 Hz; the gyroscope at 200 Hz.
  EXPECT_NE(result.out.find("10.00\n"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("/camera/gyro/sample"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("200.00\n"), std::string::npos) << result.out;
}

TEST_F(BagCli, MissingTopicExitsTwoListingTheBagsTopics) {
  const fs::path bag = smallBag();
  const ProgramResult result = slamOnBag(bag, {"--bag-preset", "tum"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find(bag.string() + ": no topic /camera/rgb/image_color (--rgb-topic); the bag has: "
                                           "/camera/accel/sample (sensor_msgs/Imu, 32 messages)"),
            std::string::npos)
      << result.err;
}

TEST_F(BagCli, TruncatedBagExitsTwoWithTheReindexHint) {
  const fs::path bag = smallBag();
  fs::resize_file(bag, fs::file_size(bag) / 2);
  const ProgramResult result = slamOnBag(bag, {"--bag-preset", "realsense"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("try `rosbag reindex " + bag.string() + "`"), std::string::npos) << result.err;
}

TEST_F(BagCli, BagWithoutImuTopicsExitsTwoForRgbdInertial) {
  const fs::path bag = smallBag();
  const ProgramResult result = slamOnBag(bag, {"--rgb-topic", "/camera/color/image_raw", "--depth-topic",
                                               "/camera/aligned_depth_to_color/image_raw"});
  EXPECT_EQ(result.exit_code, 2) << result.describe();
  EXPECT_NE(result.err.find("no IMU topic given"), std::string::npos) << result.err;
}

TEST_F(BagCli, FolderAndBagGiveTheSameTrajectoryFile) {
  const fs::path sequence = work_ / "seq";
  const ProgramResult sim = runProgram({programPath("simulate"), "--scenario", "static", "--seed", "3", "--seconds",
                                        "5", "--width", "320", "--height", "240", "--out", sequence.string()});
  ASSERT_EQ(sim.exit_code, 0) << sim.describe();
  const fs::path bag = work_ / "seq.bag";
  const io::BagTopics topics = io::bagTopicPreset("realsense-unite");
  io::test::writeBagFromFolder(sequence.string(), bag.string(), topics, /*png_colour=*/false);

  const ProgramResult folder_run =
      runProgram({programPath("rgbd_inertial"), "--settings", settings_, "--sequence", sequence.string(), "--out",
                  (work_ / "folder_run").string(), "--single-thread"});
  ASSERT_EQ(folder_run.exit_code, 0) << folder_run.describe();
  const ProgramResult bag_run = runProgram({programPath("rgbd_inertial"), "--settings", settings_, "--bag",
                                            bag.string(), "--bag-preset", "realsense-unite", "--calib",
                                            (sequence / "calib.yaml").string(), "--groundtruth",
                                            (sequence / "groundtruth.txt").string(), "--out",
                                            (work_ / "bag_run").string(), "--single-thread"});
  ASSERT_EQ(bag_run.exit_code, 0) << bag_run.describe();
  const std::string folder_trajectory = readFile(work_ / "folder_run" / "trajectory.txt");
  EXPECT_GT(std::count(folder_trajectory.begin(), folder_trajectory.end(), '\n'), 140);
  EXPECT_EQ(readFile(work_ / "bag_run" / "trajectory.txt"), folder_trajectory);
  EXPECT_NE(bag_run.out.find("frames 150\n"), std::string::npos) << bag_run.out;
  // --groundtruth: the bag run's metrics.json evaluates the same trajectory against the same poses.
  const auto ateLine = [](const std::string& out) {
    const size_t begin = out.find("ate_rmse_m ");
    return begin == std::string::npos ? std::string() : out.substr(begin, out.find('\n', begin) - begin);
  };
  EXPECT_FALSE(ateLine(folder_run.out).empty()) << folder_run.out;
  EXPECT_EQ(ateLine(bag_run.out), ateLine(folder_run.out));
  EXPECT_TRUE(fs::is_regular_file(work_ / "bag_run" / "metrics.json"));
}

// A bag that breaks part-way (frame 90 of 150 in an encoding the reader does not take): exit 2
// naming the bag, the topic, the message and the value, and the trajectory of the 90 frames before
// it written, one parseable line each.
TEST_F(BagCli, BagBrokenPartWayWritesTheTrajectorySoFar) {
  constexpr int kBadFrame = 90;
  const fs::path sequence = work_ / "seq";
  const ProgramResult sim = runProgram({programPath("simulate"), "--scenario", "static", "--seed", "3", "--seconds",
                                        "5", "--width", "320", "--height", "240", "--out", sequence.string()});
  ASSERT_EQ(sim.exit_code, 0) << sim.describe();
  const fs::path bag = work_ / "broken.bag";
  io::test::writeBagFromFolder(sequence.string(), bag.string(), io::bagTopicPreset("realsense-unite"),
                               /*png_colour=*/false, kBadFrame);
  const ProgramResult run = slamOnBag(bag, {"--bag-preset", "realsense-unite", "--calib",
                                            (sequence / "calib.yaml").string(), "--single-thread"});
  EXPECT_EQ(run.exit_code, 2) << run.describe();
  EXPECT_NE(run.err.find(bag.string()), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("topic /camera/color/image_raw message " + std::to_string(kBadFrame + 1) +
                         ": unsupported colour encoding 'yuv444'"),
            std::string::npos)
      << run.err;
  std::ifstream trajectory(work_ / "run" / "trajectory.txt");
  ASSERT_TRUE(trajectory.good());
  int poses = 0;
  for (std::string line; std::getline(trajectory, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double value = 0.0;
    int count = 0;
    while (fields >> value) ++count;
    EXPECT_EQ(count, 8) << line;
    ++poses;
  }
  EXPECT_EQ(poses, kBadFrame);
}

}  // namespace
}  // namespace ltlo::cli_test
