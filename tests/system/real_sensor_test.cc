// End to end on the faults of a real sensor (issue 28), System on short generated 320x240 sequences
// at 15 Hz, synchronous (deterministic):
//   - a camera-IMU time offset of 20 ms is recovered online within 1.5 ms (measured 19.3 ms), and
//     the run is then as accurate as the synchronised one;
//   - a lens of ~12 px at the QVGA corners (24 px at VGA) is undistorted: the run is as accurate as
//     without the lens, where ignoring it is several times worse;
//   - dropped frames (bursts of up to 3) are bridged: one map, a pose for every delivered frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "end_to_end_suite.h"
#include "ltlo/core/log.h"
#include "ltlo/core/settings.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/system/run_outputs.h"
#include "ltlo/system/system.h"

namespace ltlo::system {
namespace {

namespace fs = std::filesystem;
using test_support::EndToEndSuite;
using test_support::shortRunSettings;
using test_support::shortRunSimOptions;

constexpr double kFps = test_support::kShortRunFps;
constexpr double kSeconds = 10.0;

struct RunResult {
  int frames = 0;
  RunReport report;
  double ate_m = 0.0;
};

class RealSensorEndToEnd : public EndToEndSuite {
 public:
  static void SetUpTestSuite() { createSuiteResources("ltlo_real_sensor_"); }
  static void TearDownTestSuite() { removeSuiteResources(); }

  static std::string sequence(const std::string& name, std::uint64_t seed, const sim::SensorProfile& sensor) {
    const fs::path dir = root() / name;
    if (!fs::exists(dir / "groundtruth.txt")) {
      sim::SimOptions options = shortRunSimOptions(sim::Scenario::kStatic, seed, kSeconds);
      options.sensor = sensor;
      sim::writeSequence(options, dir.string(), 0);
    }
    return dir.string();
  }

  /// `ignore_lens`: the calibration's lens is dropped (what today's pinhole-only path did).
  static RunResult run(const std::string& dir, bool estimate_offset = true, bool ignore_lens = false) {
    Settings settings = shortRunSettings(dir);
    settings.local_mapping.estimate_time_offset = estimate_offset;
    if (ignore_lens) settings.calib.camera.lens = LensDistortion();
    io::SequenceReaderOptions reader_options;
    reader_options.calib_override = settings.calib;
    reader_options.imu_margin_s = estimate_offset ? 0.06 : 0.0;  // as rgbd_inertial
    io::SequenceReader reader = io::SequenceReader::open(dir, reader_options);
    RunResult result;
    {
      SystemOptions options;
      options.threaded = false;
      System system(settings, vocabulary(), options);
      while (std::optional<io::RgbdImuFrame> input = reader.next()) {
        system.trackFrame(*input);
        ++result.frames;
      }
      system.shutdown();
      result.report = system.report(1.0);
    }
    result.ate_m = eval::computeAte(eval::associateTrajectories(reader.groundTruth(),
                                                                toTumTrajectory(result.report.trajectory)),
                                    false)
                       .error_m.rmse;
    log::info("real sensor e2e ", fs::path(dir).filename().string(), estimate_offset ? "" : " (no offset estimate)",
              ignore_lens ? " (lens ignored)" : "", ": ATE ", result.ate_m, " m, offset ", result.report.time_offset_s,
              " s +- ", result.report.time_offset_sigma_s, " (", result.report.time_offset_updates, " estimates), ",
              result.report.counts.maps, " map(s)");
    return result;
  }
};

TEST_F(RealSensorEndToEnd, ATwentyMillisecondClockOffsetIsRecoveredOnline) {
  sim::SensorProfile late_imu;
  late_imu.name = "late-imu";
  late_imu.time_offset_enable = true;
  late_imu.time_offset_s = 0.02;
  const RunResult synchronised = run(sequence("static_sync", 2, sim::SensorProfile()));
  const std::string late = sequence("static_late_imu", 2, late_imu);
  const RunResult estimated = run(late);
  ASSERT_EQ(estimated.report.counts.frames_with_pose, estimated.frames);
  ASSERT_TRUE(estimated.report.time_offset_estimated);
  EXPECT_NEAR(estimated.report.time_offset_s, 0.02, 0.0015);
  EXPECT_LT(estimated.report.time_offset_sigma_s, 0.002);
  // The synchronised run's estimate stays at 0.
  EXPECT_NEAR(synchronised.report.time_offset_s, 0.0, 0.0015);
  // With the estimate the run is as good as the synchronised one (measured 6.3 against 6.2 mm;
  // holding the offset at the calibration's 0 gave 6.5 mm on this slow static run, 11.3 mm on the
  // 20 s VGA static run with 30 ms).
  EXPECT_LT(estimated.ate_m, 1.3 * synchronised.ate_m + 0.002);
}

TEST_F(RealSensorEndToEnd, ALensIsUndistortedNotIgnored) {
  sim::SensorProfile lens;
  lens.name = "lens";
  lens.lens_enable = true;
  lens.lens = sim::lensPreset(sim::LensPreset::kRadTanStrong);
  const RunResult pinhole = run(sequence("static_pinhole_3", 3, sim::SensorProfile()));
  const std::string distorted = sequence("static_lens_3", 3, lens);
  const RunResult undistorted = run(distorted);
  const RunResult ignored = run(distorted, true, true);
  ASSERT_EQ(undistorted.report.counts.frames_with_pose, undistorted.frames);
  EXPECT_EQ(undistorted.report.counts.maps, 1);
  // Measured 5.5 mm undistorted, 4.7 mm on the same seed without the lens, 17.1 mm ignoring it.
  EXPECT_LT(undistorted.ate_m, 1.3 * pinhole.ate_m + 0.002);
  EXPECT_GT(ignored.ate_m, 2.0 * undistorted.ate_m);
}

TEST_F(RealSensorEndToEnd, DroppedFramesAreBridgedInOneMap) {
  sim::SensorProfile drops;
  drops.name = "drops";
  drops.drops_enable = true;
  drops.drop_rate = 0.05;
  drops.drop_max_burst = 3;
  const RunResult result = run(sequence("static_drops_1", 1, drops));
  EXPECT_LT(result.frames, static_cast<int>(kSeconds * kFps) - 3);  // frames were dropped
  EXPECT_EQ(result.report.counts.frames_with_pose, result.frames);
  EXPECT_EQ(result.report.counts.maps, 1);
  EXPECT_EQ(result.report.counts.maps_created, 0);
  EXPECT_GE(result.report.counts.frames_tracked, result.frames - 1);
  EXPECT_LT(result.ate_m, 0.015);
}

}  // namespace
}  // namespace ltlo::system
