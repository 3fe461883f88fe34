// End to end (issue 6): System (tracking + local mapping + loop closing on one Atlas) on short
// generated 320x240 sequences. Bounds on ATE catch a regression in any thread: tracking alone
// drifts past them, a broken local BA or IMU initialisation shows in the error or the counts, and
// every frame after the first must carry a pose, a lap of the room must close a loop. The outputs
// are written and read back.
//
// The sanitizer script (scripts/sanitize_e2e.sh) runs RgbdInertialThreaded and the loop test of this
// binary under TSan and ASan/UBSan.
#include <algorithm>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <functional>
#include <memory>

#include "bow/vocabulary.h"
#include "end_to_end_suite.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/settings.h"
#include "ltlo/eval/mask_iou.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/system/run_outputs.h"
#include "ltlo/system/system.h"

namespace ltlo::system {
namespace {

namespace fs = std::filesystem;

using test_support::EndToEndSuite;
using test_support::sourceDir;

/// Options of a run with or without the IMU, threaded or synchronous; the rest at their defaults.
SystemOptions systemOptions(bool use_imu, bool threaded) {
  SystemOptions options;
  options.use_imu = use_imu;
  options.threaded = threaded;
  return options;
}

/// Frame rate of the generated sequences: 15 Hz halves simulation and run time against 30 Hz and
/// doubles the motion between frames (about 3 cm), a harder case for tracking.
constexpr double kFps = 15.0;

struct RunResult {
  int frames = 0;
  SystemCounts counts;
  std::vector<FramePose> trajectory;
  RunReport report;
  double ate_rmse_m = 0.0;
  double ate_max_m = 0.0;
  double ate_online_rmse_m = 0.0;  ///< of report.trajectory_online (the poses as tracked)
};

/// Generated sequences shared by the tests of this file (written once, removed at exit).
class SystemEndToEnd : public EndToEndSuite {
 protected:
  static void SetUpTestSuite() { createSuiteResources("ltlo_system_"); }
  static void TearDownTestSuite() { removeSuiteResources(); }

  /// The sequence of `scenario`, `seconds` long at `fps`, written on first use.
  static std::string sequence(sim::Scenario scenario, double seconds, std::uint64_t seed, double fps = kFps,
                              double mean_speed_mps = sim::SimOptions().mean_speed_mps) {
    const fs::path dir = root() / (sim::scenarioName(scenario) + "_" + std::to_string(static_cast<int>(seconds)) +
                                   "s_seed" + std::to_string(seed) + "_" + std::to_string(static_cast<int>(fps)) + "hz");
    if (!fs::exists(dir / "groundtruth.txt")) {
      sim::SimOptions options;
      options.width_px = 320;
      options.height_px = 240;
      options.scenario = scenario;
      options.seed = seed;
      options.duration_s = seconds;
      options.fps = fps;
      options.mean_speed_mps = mean_speed_mps;
      sim::writeSequence(options, dir.string(), 0);
    }
    return dir.string();
  }

  static Settings settingsFor(const std::string& dir, bool segment = false) {
    Settings settings = Settings::load((sourceDir() / "config_yaml/synthetic.yaml").string(),
                                       (fs::path(dir) / "calib.yaml").string());
    settings.orb.num_features = 500;  // 320x240: half the VGA budget
    // Short runs: keyframes twice a second and the IMU initialised after 8 of them (about 4 s),
    // so the inertial path of every thread is exercised within seconds.
    settings.keyframe.max_interval_s = 0.5;
    settings.imu_init.min_keyframes = 8;
    settings.segmentation.enable = segment;
    return settings;
  }

  /// `tweak` changes the settings of settingsFor before the run.
  static RunResult run(const std::string& dir, const SystemOptions& options, bool segment = false,
                       const std::function<void(Settings&)>& tweak = {}) {
    io::SequenceReader reader = io::SequenceReader::open(dir);
    RunResult result;
    {
      Settings settings = settingsFor(dir, segment);
      if (tweak) tweak(settings);
      System system(settings, vocabulary(), options);
      while (std::optional<io::RgbdImuFrame> input = reader.next()) {
        system.trackFrame(*input);
        ++result.frames;
      }
      system.shutdown();
      result.report = system.report(1.0);
    }
    result.counts = result.report.counts;
    result.trajectory = result.report.trajectory;
    const eval::MatchedTrajectories matched =
        eval::associateTrajectories(reader.groundTruth(), toTumTrajectory(result.trajectory));
    if (matched.est.size() >= 3) {
      const eval::AteResult ate = eval::computeAte(matched, false);
      result.ate_rmse_m = ate.error_m.rmse;
      result.ate_max_m = ate.error_m.max;
    }
    const eval::MatchedTrajectories matched_online =
        eval::associateTrajectories(reader.groundTruth(), toTumTrajectory(result.report.trajectory_online));
    if (matched_online.est.size() >= 3) result.ate_online_rmse_m = eval::computeAte(matched_online, false).error_m.rmse;
    log::info("e2e ", fs::path(dir).filename().string(), (options.use_imu ? " rgbd-inertial" : " rgbd"),
              (options.threaded ? " threaded" : " synchronous"), ": ATE rmse ", result.ate_rmse_m, " m, max ",
              result.ate_max_m, " m, ", result.counts.keyframes, " keyframes, ", result.counts.map_points,
              " points, ", result.counts.maps, " map(s), ", result.counts.loops, " loop(s), imu ",
              result.counts.imu_initialised);
    return result;
  }

  /// Every frame has a pose (a static sequence initialises on its first frame) and times increase.
  static void expectPoseForEveryFrame(const RunResult& result) {
    EXPECT_EQ(result.counts.frames, result.frames);
    EXPECT_EQ(result.counts.frames_with_pose, result.frames);
    ASSERT_EQ(static_cast<int>(result.trajectory.size()), result.frames);
    for (std::size_t i = 1; i < result.trajectory.size(); ++i) {
      ASSERT_GT(result.trajectory[i].t_s, result.trajectory[i - 1].t_s);
    }
  }

};


constexpr double kStaticSeconds = 8.0;
constexpr std::uint64_t kStaticSeed = 2;

TEST_F(SystemEndToEnd, RgbdInertialThreaded) {
  const std::string dir = sequence(sim::Scenario::kStatic, kStaticSeconds, kStaticSeed);
  const RunResult result = run(dir, systemOptions(true, true));
  expectPoseForEveryFrame(result);
  EXPECT_LT(result.ate_rmse_m, 0.025);
  EXPECT_LT(result.ate_max_m, 0.05);
  EXPECT_TRUE(result.counts.imu_initialised);  // local mapping initialised the IMU
  EXPECT_GE(result.counts.keyframes, 10);
  EXPECT_GE(result.counts.frames_tracked, result.frames - 5);
  EXPECT_EQ(result.counts.maps, 1);

  // The outputs: written, re-read, one trajectory line per frame.
  const fs::path out = root() / "run_rgbd_inertial";
  io::SequenceReader reader = io::SequenceReader::open(dir);
  const WrittenOutputs written = writeRunOutputs(out.string(), result.report, reader.groundTruth(), 0.5);
  EXPECT_EQ(io::readTumTrajectory((out / "trajectory.txt").string()).size(), static_cast<std::size_t>(result.frames));
  EXPECT_EQ(readKeyFrames((out / "keyframes.txt").string()).size(), static_cast<std::size_t>(result.counts.keyframes));
  EXPECT_EQ(readStaticMapPly((out / "static_map.ply").string()).size(), static_cast<std::size_t>(written.static_points));
  EXPECT_GT(written.static_points, 500);
  ASSERT_TRUE(written.has_metrics);
  EXPECT_NEAR(written.metrics.number("ate_rmse_m"), result.ate_rmse_m, 1e-12);
  EXPECT_TRUE(written.metrics.has("tracking_frame_median_ms"));
  EXPECT_TRUE(written.metrics.has("mapping_keyframe_median_ms"));
}

// One lap of the room (the robot is back at its start after about 25 s at 0.55 m/s) at 12 Hz: the
// loop-closing thread must recognise the place and close the loop in the one map.
TEST_F(SystemEndToEnd, RgbdOnlyThreadedClosesTheLoop) {
  const RunResult result =
      run(sequence(sim::Scenario::kStatic, 27.0, kStaticSeed, /*fps=*/12.0, /*mean_speed_mps=*/0.55),
          systemOptions(false, true));
  std::printf("RGB-D only, threaded, one lap: ATE %.4f m, max %.4f m, %d loop(s)\n", result.ate_rmse_m,
              result.ate_max_m, result.counts.loops);
  expectPoseForEveryFrame(result);
  EXPECT_LT(result.ate_rmse_m, 0.03);
  // A frame tracked while a correction lands kept it without the world gate (0.075-0.091 m under
  // load); with it 0.026-0.033 m, once 0.061 m under heavy load (an early extra loop, 8 cm).
  EXPECT_LT(result.ate_max_m, 0.07);
  EXPECT_FALSE(result.counts.imu_initialised);
  EXPECT_GE(result.counts.frames_tracked, result.frames - 5);
  EXPECT_GE(result.counts.loops, 1);
  EXPECT_EQ(result.counts.merges, 0);
  EXPECT_EQ(result.counts.maps, 1);

  // The online stream: a pose per frame at the same times, as tracked. Before the loop its poses
  // are the final ones up to the correction's drift; after it the corrected trajectory moved away
  // from what tracking returned (the drift the loop removed), so the two differ.
  const std::vector<FramePose>& online = result.report.trajectory_online;
  ASSERT_EQ(online.size(), result.trajectory.size());
  double max_gap_m = 0.0;
  for (std::size_t i = 0; i < online.size(); ++i) {
    ASSERT_EQ(online[i].t_s, result.trajectory[i].t_s);
    max_gap_m = std::max(max_gap_m, (online[i].T_w_c.translation() - result.trajectory[i].T_w_c.translation()).norm());
  }
  std::printf("online: ATE %.4f m (final %.4f m), largest online-final gap %.4f m\n", result.ate_online_rmse_m,
              result.ate_rmse_m, max_gap_m);
  EXPECT_GT(max_gap_m, 1e-3);
  EXPECT_LT(result.ate_online_rmse_m, 0.1);
}

TEST_F(SystemEndToEnd, SynchronousIsDeterministicAndAccurate) {
  const std::string dir = sequence(sim::Scenario::kStatic, kStaticSeconds, kStaticSeed);
  const RunResult result = run(dir, systemOptions(true, false));
  expectPoseForEveryFrame(result);
  EXPECT_LT(result.ate_rmse_m, 0.02);
  EXPECT_TRUE(result.counts.imu_initialised);
  EXPECT_GE(result.counts.keyframes, 10);
  // Mapping and loop closing inside trackFrame: a second run gives the same trajectory.
  const RunResult again = run(dir, systemOptions(true, false));
  ASSERT_EQ(again.trajectory.size(), result.trajectory.size());
  ASSERT_EQ(again.report.trajectory_online.size(), result.trajectory.size());
  for (std::size_t i = 0; i < result.trajectory.size(); ++i) {
    ASSERT_EQ(again.report.trajectory_online[i].T_w_c.translation(),
              result.report.trajectory_online[i].T_w_c.translation()) << "frame " << i;
  }
  // No loop on 8 s: the online poses are the final ones up to local BA's later refinement.
  EXPECT_LT(result.ate_online_rmse_m, 2.0 * result.ate_rmse_m + 0.005);
  for (std::size_t i = 0; i < result.trajectory.size(); ++i) {
    ASSERT_EQ(again.trajectory[i].T_w_c.translation(), result.trajectory[i].T_w_c.translation()) << "frame " << i;
  }
  EXPECT_EQ(again.counts.keyframes, result.counts.keyframes);
  EXPECT_EQ(again.counts.map_points, result.counts.map_points);
}

// The keyframes culled on a revisit: every frame that used one as reference keeps following it
// through its stand-in (no image data), so a run of many laps does not keep every keyframe it ever
// made (issue 32). The lap above, RGB-D-inertial and threaded (the tracking thread swaps references
// while local mapping culls; scripts/sanitize_e2e.sh runs it under TSan and ASan), with culling that a
// 27-s run reaches (redundancy 0.5, the IMU chain cut from 2 s back): culled keyframes end held as
// stand-ins only, and the trajectory that follows them keeps the bounds of the lap.
TEST_F(SystemEndToEnd, CulledKeyFramesAreHeldWithoutTheirImageData) {
  const RunResult result =
      run(sequence(sim::Scenario::kStatic, 27.0, kStaticSeed, /*fps=*/12.0, /*mean_speed_mps=*/0.55),
          systemOptions(true, true), false, [](Settings& settings) {
            settings.local_mapping.redundant_ratio = 0.5;
            settings.local_mapping.cull_imu_cut_age_s = 2.0;
          });
  std::printf("one lap, culling: %d keyframes, %d culled ones held as stand-ins, %d whole; ATE %.4f m\n",
              result.counts.keyframes, result.counts.keyframes_released, result.counts.keyframes_culled_held,
              result.ate_rmse_m);
  expectPoseForEveryFrame(result);
  EXPECT_GT(result.counts.keyframes_released, 5);
  EXPECT_EQ(result.counts.keyframes_culled_held, 0);
  // A sanity bound: culling this hard, threaded, is timing-dependent (7-11 mm in Release, 72 mm once
  // under ASan's slow threads, whose loop BA aborted); that a stand-in gives its keyframe's pose to the
  // bit is KeyFrameOwnership.AStandInOf...'s check, and the 5- and 10-minute runs' (docs/results.md).
  EXPECT_LT(result.ate_rmse_m, 0.1);
}

TEST_F(SystemEndToEnd, LongTermOcclusionRunsWithAPoseForEveryFrame) {
  const RunResult result = run(sequence(sim::Scenario::kLtlo, 4.0, 1), systemOptions(true, true));
  // Boxes may cover the first frame; from the first initialisation on, every frame has a pose.
  EXPECT_EQ(result.counts.frames, result.frames);
  EXPECT_GE(result.counts.frames_with_pose, result.frames - 10);
  EXPECT_EQ(static_cast<int>(result.trajectory.size()), result.counts.frames_with_pose);
  // What this test checks is the pose on every frame while the box covers the view, threaded. Its
  // ATE is large for the system (measured 0.10-0.20 m in four runs): 4 s at 15 Hz end while the box
  // enters, right when local mapping's first IMU refinement runs on a short window (it logs
  // accelerometer biases near 1 m/s^2 and inertial residuals 4.5x the noise model). So the bound
  // only catches a run that loses the map; accuracy under occlusion is occlusion_test.cc's.
  EXPECT_LT(result.ate_rmse_m, 0.5);
}

// Issue 11: with the dynamic segmentation (depth clusters + the dense solve of thesis Eq. 59-64)
// the pushed boxes of the long-term occlusion scenario are labelled dynamic on every frame: the
// masks the writer thread puts in segmentation/ match the sequence's masks/.
TEST_F(SystemEndToEnd, LongTermOcclusionSegmentsTheBoxes) {
  const std::string dir = sequence(sim::Scenario::kLtlo, 4.0, 1);
  const fs::path masks_dir = root() / "ltlo_segmentation";
  SystemOptions options = systemOptions(true, true);
  options.segmentation_dir = masks_dir.string();
  const RunResult result = run(dir, options, /*segment=*/true);
  EXPECT_GE(result.counts.frames_with_pose, result.frames - 10);
  const eval::MaskIouResult iou = eval::evaluateMaskFolders((fs::path(dir) / "masks").string(), masks_dir.string());
  log::info("e2e ltlo segmentation: static IoU ", iou.mean_static_iou, " (", iou.num_frames, " frames), occluded ",
            iou.mean_static_iou_occluded, " (", iou.num_occluded_frames, " frames)");
  EXPECT_EQ(iou.num_frames, result.frames);  // one mask per frame
  ASSERT_GT(iou.num_occluded_frames, 5);      // a box covers more than 40 % of the view
  EXPECT_GE(iou.mean_static_iou, 0.9);
  // Tracking on static features only: the unsegmented run above follows the box (~0.15 m).
  EXPECT_LT(result.ate_rmse_m, 0.06);
}

TEST_F(SystemEndToEnd, FrameOfTheWrongSizeIsBadInput) {
  sim::SimOptions camera;  // a 320x240 calibration, no sequence needed
  camera.width_px = 320;
  camera.height_px = 240;
  const fs::path calib = root() / "calib_320x240.yaml";
  camera.sensorCalib().write(calib.string());
  const Settings settings = Settings::load((sourceDir() / "config_yaml/synthetic.yaml").string(), calib.string());
  System system(settings, vocabulary(), systemOptions(true, false));
  io::RgbdImuFrame input;
  input.color_bgr = cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0));
  input.depth_m = cv::Mat(480, 640, CV_32F, cv::Scalar(0.0f));
  input.color_path = "rgb/0.000000.png";
  try {
    system.trackFrame(input);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("rgb/0.000000.png: image is 640x480 but the calibration says 320x240"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(system.counts().frames, 0);
}

}  // namespace
}  // namespace ltlo::system
