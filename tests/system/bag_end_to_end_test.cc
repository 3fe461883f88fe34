// End to end from a ROS 1 bag (issue 29): a generated sequence and the same sequence written to a
// bag (rosbag's writer; raw bgr8 and PNG-compressed colour, 16UC1 depth, one Imu topic) give the
// same trajectory, bit for bit, in the synchronous (deterministic) mode. The bag path goes through
// the prefetcher as the programs read it; the folder path too.
#include <gtest/gtest.h>

#include <filesystem>

#include "end_to_end_suite.h"
#include "ltlo/core/log.h"
#include "ltlo/core/settings.h"
#include "ltlo/io/frame_prefetcher.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/system/system.h"
#include "test_bag_writer.h"

namespace ltlo::system {
namespace {

namespace fs = std::filesystem;
using test_support::EndToEndSuite;
using test_support::sourceDir;

class BagEndToEnd : public EndToEndSuite {
 public:
  static void SetUpTestSuite() { createSuiteResources("ltlo_bag_e2e_"); }
  static void TearDownTestSuite() { removeSuiteResources(); }

  static std::string sequence() {
    const fs::path dir = root() / "static_10s";
    if (!fs::exists(dir / "calib.yaml")) {
      sim::SimOptions options;
      options.width_px = 320;
      options.height_px = 240;
      options.scenario = sim::Scenario::kStatic;
      options.seed = 2;
      options.duration_s = 10.0;
      options.fps = 15.0;
      sim::writeSequence(options, dir.string(), 0);
    }
    return dir.string();
  }

  static std::vector<FramePose> run(io::SequenceReader reader, const Settings& settings, int* frames) {
    SystemOptions options;
    options.use_imu = true;
    options.threaded = false;
    System system(settings, vocabulary(), options);
    *frames = 0;
    {
      io::FramePrefetcher prefetcher(reader, 4);
      while (std::optional<io::RgbdImuFrame> input = prefetcher.next()) {
        system.trackFrame(*input);
        ++*frames;
      }
    }
    system.shutdown();
    return system.report(1.0).trajectory;
  }
};

TEST_F(BagEndToEnd, BagGivesTheFolderTrajectoryBitForBit) {
  const std::string dir = sequence();
  Settings settings = Settings::load((sourceDir() / "config_yaml/synthetic.yaml").string(),
                                     (fs::path(dir) / "calib.yaml").string());
  settings.orb.num_features = 500;
  settings.keyframe.max_interval_s = 0.5;
  settings.imu_init.min_keyframes = 8;
  io::SequenceReaderOptions options;
  options.sequence = settings.sequence;
  options.calib_override = settings.calib;
  options.read_ground_truth = false;

  int folder_frames = 0;
  const std::vector<FramePose> folder = run(io::SequenceReader::open(dir, options), settings, &folder_frames);
  ASSERT_EQ(folder_frames, 150);
  ASSERT_GT(folder.size(), 140u);

  const io::BagTopics topics = io::bagTopicPreset("realsense-unite");
  for (const bool png_colour : {false, true}) {
    const std::string bag = (root() / (png_colour ? "png.bag" : "raw.bag")).string();
    io::test::writeBagFromFolder(dir, bag, topics, png_colour);
    int bag_frames = 0;
    const std::vector<FramePose> from_bag = run(io::SequenceReader::openBag(bag, topics, options), settings, &bag_frames);
    EXPECT_EQ(bag_frames, folder_frames);
    ASSERT_EQ(from_bag.size(), folder.size()) << bag;
    double worst_m = 0.0;
    int differing = 0;
    for (size_t i = 0; i < folder.size(); ++i) {
      EXPECT_EQ(from_bag[i].t_s, folder[i].t_s);
      worst_m = std::max(worst_m, (from_bag[i].T_w_c.translation() - folder[i].T_w_c.translation()).norm());
      differing += from_bag[i].T_w_c.matrix() != folder[i].T_w_c.matrix();
    }
    log::info("bag e2e ", bag, ": ", from_bag.size(), " poses, ", differing, " differ, worst ", worst_m, " m");
    EXPECT_EQ(differing, 0) << bag << ": worst position difference " << worst_m << " m";
  }
}

}  // namespace
}  // namespace ltlo::system
