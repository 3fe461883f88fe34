// Resources shared by the tests of one end-to-end suite: a temporary folder for the sequences the
// simulator writes and the runs' outputs (removed when the suite ends), and the shipped vocabulary,
// loaded once per suite.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

#include "bow/vocabulary.h"
#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/sim/sim_options.h"

namespace ltlo::test_support {

/// The source tree: LTLO_SOURCE_DIR (set by ctest) or the working folder.
inline std::filesystem::path sourceDir() {
  const char* root = std::getenv("LTLO_SOURCE_DIR");
  return root != nullptr ? std::filesystem::path(root) : std::filesystem::current_path();
}

/// Frame rate of the short end-to-end sequences: half the simulation and run time of 30 Hz, twice
/// the motion between frames.
inline constexpr double kShortRunFps = 15.0;

/// The simulator's options for a short end-to-end sequence: 320x240 at kShortRunFps.
inline sim::SimOptions shortRunSimOptions(sim::Scenario scenario, std::uint64_t seed, double seconds) {
  sim::SimOptions options;
  options.width_px = 320;
  options.height_px = 240;
  options.scenario = scenario;
  options.seed = seed;
  options.duration_s = seconds;
  options.fps = kShortRunFps;
  return options;
}

/// The settings of a run on such a sequence: config_yaml/synthetic.yaml with the sequence's
/// calib.yaml, half the VGA feature budget (320x240), keyframes twice a second and the IMU
/// initialised after 8 of them (about 4 s).
inline Settings shortRunSettings(const std::string& sequence_dir) {
  Settings settings = Settings::load((sourceDir() / "config_yaml/synthetic.yaml").string(),
                                     (std::filesystem::path(sequence_dir) / "calib.yaml").string());
  settings.orb.num_features = 500;
  settings.keyframe.max_interval_s = 0.5;
  settings.imu_init.min_keyframes = 8;
  return settings;
}

/// The pose of the ground truth stamped nearest to t_s (a non-empty trajectory).
inline SE3 truthNearest(const io::Trajectory& truth, double t_s) {
  const io::StampedPose* best = &truth.front();
  for (const io::StampedPose& pose : truth) {
    if (std::abs(pose.t_s - t_s) < std::abs(best->t_s - t_s)) best = &pose;
  }
  return best->T_w_x;
}

/// Base of the end-to-end fixtures. A derived suite calls createSuiteResources(prefix) from its
/// SetUpTestSuite and removeSuiteResources() from its TearDownTestSuite.
class EndToEndSuite : public ::testing::Test {
 protected:
  /// Creates <tmp>/<prefix><pid>/ and loads Vocabulary/ltlo_orb_k10_L5.bin.
  static void createSuiteResources(const std::string& prefix) {
    root_ = std::filesystem::temp_directory_path() / (prefix + std::to_string(::getpid()));
    std::filesystem::create_directories(root_);
    vocabulary_ = std::make_shared<const bow::Vocabulary>(
        bow::Vocabulary::load((sourceDir() / "Vocabulary/ltlo_orb_k10_L5.bin").string()));
  }
  static void removeSuiteResources() {
    std::filesystem::remove_all(root_);
    root_.clear();
    vocabulary_.reset();
  }
  static const std::filesystem::path& root() { return root_; }
  static const std::shared_ptr<const bow::Vocabulary>& vocabulary() { return vocabulary_; }

 private:
  static inline std::filesystem::path root_;
  static inline std::shared_ptr<const bow::Vocabulary> vocabulary_;
};

}  // namespace ltlo::test_support
