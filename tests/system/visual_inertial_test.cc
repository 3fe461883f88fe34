// End to end, visual-inertial backbone (issue 10): System on short generated 320x240 sequences.
//   - the IMU beats RGB-D only on the same frames (both bounded);
//   - black frames are bridged by the IMU: the predicted positions stay within what the IMU's
//     noise allows, tracking resumes in the same map;
//   - the --oracle-masks ablation on a long-term-occlusion run stays within 30 mm ATE;
//   - the estimator never reads masks/: a copy of a sequence without it gives the same trajectory.
// Runs are synchronous (mapping and loop closing inside trackFrame): deterministic.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <memory>

#include "bow/vocabulary.h"
#include "end_to_end_suite.h"
#include "ltlo/core/assert.h"
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

struct RunResult {
  int frames = 0;
  SystemCounts counts;
  std::vector<FramePose> trajectory;
  /// IMU-carried stretches as the IMU predicted them (trajectory: smoothed once anchored)
  std::vector<FramePose> predicted_trajectory;
  io::Trajectory ground_truth;
  eval::AteResult ate;  ///< all frames with a pose
};

class VisualInertialEndToEnd : public EndToEndSuite {
 public:
  static void SetUpTestSuite() { createSuiteResources("ltlo_vi_"); }
  static void TearDownTestSuite() { removeSuiteResources(); }

  static std::string sequence(const std::string& name, sim::Scenario scenario, double seconds, std::uint64_t seed,
                              std::vector<sim::SensorOutage> outages = {}) {
    const fs::path dir = root() / name;
    if (!fs::exists(dir / "groundtruth.txt")) {
      sim::SimOptions options = shortRunSimOptions(scenario, seed, seconds);
      options.outages = std::move(outages);
      sim::writeSequence(options, dir.string(), 0);
    }
    return dir.string();
  }

  static Settings settingsFor(const std::string& dir) { return shortRunSettings(dir); }

  static RunResult run(const std::string& dir, bool use_imu, bool oracle_masks = false) {
    io::SequenceReaderOptions reader_options;
    reader_options.read_masks = oracle_masks;
    io::SequenceReader reader = io::SequenceReader::open(dir, reader_options);
    RunResult result;
    {
      SystemOptions options;
      options.use_imu = use_imu;
      options.threaded = false;
      options.oracle_masks = oracle_masks;
      System system(settingsFor(dir), vocabulary(), options);
      while (std::optional<io::RgbdImuFrame> input = reader.next()) {
        system.trackFrame(*input);
        ++result.frames;
      }
      system.shutdown();
      const RunReport report = system.report(1.0);
      result.counts = report.counts;
      result.trajectory = report.trajectory;
      result.predicted_trajectory = system.trajectory(CarriedCorrection::kNone);
    }
    result.ground_truth = reader.groundTruth();
    result.ate = eval::computeAte(eval::associateTrajectories(result.ground_truth, toTumTrajectory(result.trajectory)),
                                  false);
    log::info("vi e2e ", fs::path(dir).filename().string(), use_imu ? " rgbd-inertial" : " rgbd",
              oracle_masks ? " oracle-masks" : "", ": ATE rmse ", result.ate.error_m.rmse, " m, max ",
              result.ate.error_m.max, " m, ", result.counts.frames_tracked, "/", result.frames, " tracked, ",
              result.counts.keyframes, " keyframes, ", result.counts.maps, " map(s), imu ",
              result.counts.imu_initialised);
    return result;
  }

  /// Position error (m) of every frame with a pose, by timestamp, after the SE3 alignment
  /// (Umeyama) of the frames outside [skip_begin_s, skip_end_s).
  static std::vector<std::pair<double, double>> alignedErrors(const RunResult& run, double skip_begin_s = 0.0,
                                                              double skip_end_s = 0.0, bool predicted = false) {
    const eval::MatchedTrajectories matched = eval::associateTrajectories(
        run.ground_truth, toTumTrajectory(predicted ? run.predicted_trajectory : run.trajectory));
    std::vector<Vec3> p_est, p_gt;
    for (std::size_t i = 0; i < matched.est.size(); ++i) {
      const double t = matched.est[i].t_s;
      if (t >= skip_begin_s && t < skip_end_s) continue;
      p_est.push_back(matched.est[i].T_w_x.translation());
      p_gt.push_back(matched.gt[i].T_w_x.translation());
    }
    const Sim3 S_gt_est = eval::umeyamaAlignment(p_est, p_gt, false);
    std::vector<std::pair<double, double>> errors;
    for (std::size_t i = 0; i < matched.est.size(); ++i) {
      const Vec3 p = S_gt_est * matched.est[i].T_w_x.translation();
      errors.emplace_back(matched.est[i].t_s, (p - matched.gt[i].T_w_x.translation()).norm());
    }
    return errors;
  }

};


/// The static 10 s RGB-D-inertial run, shared by the tests that need it.
const RunResult& staticInertialRun() {
  static const RunResult result = VisualInertialEndToEnd::run(
      VisualInertialEndToEnd::sequence("static_10s", sim::Scenario::kStatic, 10.0, 2), true);
  return result;
}

TEST_F(VisualInertialEndToEnd, ImuBeatsRgbdOnlyOnTheSameFrames) {
  const std::string dir = sequence("static_10s", sim::Scenario::kStatic, 10.0, 2);
  const RunResult& inertial = staticInertialRun();
  const RunResult visual = run(dir, false);
  ASSERT_EQ(inertial.counts.frames_with_pose, inertial.frames);
  ASSERT_EQ(visual.counts.frames_with_pose, visual.frames);
  EXPECT_TRUE(inertial.counts.imu_initialised);
  EXPECT_EQ(inertial.counts.maps, 1);
  EXPECT_EQ(visual.counts.maps, 1);
  EXPECT_LT(visual.ate.error_m.rmse, 0.02);
  EXPECT_LT(inertial.ate.error_m.rmse, visual.ate.error_m.rmse);
}

/// Largest distance, over [t_begin_s, t_end_s), between the ground truth and its constant-velocity
/// extrapolation from t_begin_s (velocity from the last two ground-truth poses before it): what a
/// motion model without the IMU would predict even with the exact velocity.
double constantVelocityError(const io::Trajectory& ground_truth, double t_begin_s, double t_end_s) {
  std::size_t start = 0;
  while (start + 1 < ground_truth.size() && ground_truth[start + 1].t_s <= t_begin_s) ++start;
  LTLO_ASSERT(start >= 1, "no ground truth before the gap");
  const Vec3 p0 = ground_truth[start].T_w_x.translation();
  const Vec3 v = (p0 - ground_truth[start - 1].T_w_x.translation()) /
                 (ground_truth[start].t_s - ground_truth[start - 1].t_s);
  double max_m = 0.0;
  for (std::size_t i = start; i < ground_truth.size() && ground_truth[i].t_s < t_end_s; ++i) {
    const Vec3 predicted = p0 + v * (ground_truth[i].t_s - ground_truth[start].t_s);
    max_m = std::max(max_m, (predicted - ground_truth[i].T_w_x.translation()).norm());
  }
  return max_m;
}

// 1.5 s of black frames (no colour, no depth) 4 s after the IMU initialisation, the IMU running:
// every black frame gets the IMU-only prediction, and tracking resumes in the same map, without
// relocalisation or a new map. The prediction's error is dominated by the accelerometer bias the
// initialisation could not separate from gravity over a few seconds of motion: 0.5 |db| t^2 =
// 1.1 |db| at t = 1.5 s, plus the velocity and attitude error at the start and the noise
// (0.01 m/s^2/sqrt(Hz): sigma_a sqrt(t^3 / 3) = 1 cm). The simulator draws the bias with 0.03 m/s^2
// per axis, so one seed's error is a draw: an unreduced bias alone gives 5.4 cm on average (the
// mean norm, 1.6 sigma) and 10 cm at 3 sigma. One seed can therefore not show a bound tighter than
// that; four seeds bound the mean, and each seed's error is compared with what a motion model
// without the IMU would predict. Once tracking resumes, the output trajectory spreads the
// prediction's end error over the gap (Tracking.SmoothCarriedFrames): its black frames must end
// closer to the truth than the prediction, within the tracked frames' error plus what the error
// model's shape leaves.
TEST_F(VisualInertialEndToEnd, BlackFramesAreBridgedByTheImu) {
  constexpr double kBlackStart = 6.0, kBlackSeconds = 1.5;
  constexpr int kSeeds = 4;
  double sum_predicted_m = 0.0, sum_smoothed_m = 0.0;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const std::string dir =
        sequence("static_black_" + std::to_string(seed), sim::Scenario::kStatic, 10.0, static_cast<std::uint64_t>(seed),
                 {sim::SensorOutage{sim::SensorOutage::Kind::kBlack, kBlackStart, kBlackSeconds}});
    const RunResult inertial = run(dir, true);
    ASSERT_EQ(inertial.counts.frames_with_pose, inertial.frames);
    EXPECT_TRUE(inertial.counts.imu_initialised);
    EXPECT_EQ(inertial.counts.maps, 1);
    EXPECT_EQ(inertial.counts.maps_created, 0);
    const auto maxErrors = [&](bool predicted) {
      double max_black_m = 0.0, max_tracked_m = 0.0;
      for (const auto& [t_s, error_m] :
           alignedErrors(inertial, kBlackStart, kBlackStart + kBlackSeconds, predicted)) {
        const bool black = t_s >= kBlackStart && t_s < kBlackStart + kBlackSeconds;
        (black ? max_black_m : max_tracked_m) = std::max(black ? max_black_m : max_tracked_m, error_m);
      }
      return std::make_pair(max_black_m, max_tracked_m);
    };
    const auto [predicted_black_m, tracked_m] = maxErrors(true);
    const double smoothed_black_m = maxErrors(false).first;
    const double constant_velocity_m =
        constantVelocityError(inertial.ground_truth, kBlackStart, kBlackStart + kBlackSeconds);
    log::info("vi e2e blackout seed ", seed, ": max error over the black frames ", predicted_black_m,
              " m predicted, ", smoothed_black_m, " m smoothed (constant velocity from the true state: ",
              constant_velocity_m, " m), ", tracked_m, " m elsewhere; ", inertial.counts.frames_tracked, " of ",
              inertial.frames, " tracked");
    EXPECT_LT(predicted_black_m, 0.10);  // 3 sigma of an unreduced bias
    EXPECT_LT(predicted_black_m, 0.5 * constant_velocity_m);
    EXPECT_LT(smoothed_black_m, std::max(predicted_black_m, tracked_m + 0.01));
    EXPECT_LT(tracked_m, 0.03);
    // Black frames are not tracked; every other frame is (the first after the gap included).
    EXPECT_GE(inertial.counts.frames_tracked, inertial.frames - static_cast<int>(kBlackSeconds * kFps) - 1);
    sum_predicted_m += predicted_black_m;
    sum_smoothed_m += smoothed_black_m;
  }
  EXPECT_LT(sum_predicted_m / kSeeds, 0.054);  // the mean error of an unreduced bias
  EXPECT_LT(sum_smoothed_m / kSeeds, 0.5 * sum_predicted_m / kSeeds);
}

// Without --oracle-masks nothing of the estimator opens masks/: a copy of the sequence without the
// folder gives the very same trajectory (synchronous runs are deterministic).
TEST_F(VisualInertialEndToEnd, SequenceWithoutMasksFolderGivesTheSameTrajectory) {
  const fs::path original = sequence("static_10s", sim::Scenario::kStatic, 10.0, 2);
  ASSERT_TRUE(fs::is_directory(original / "masks"));
  const fs::path copy = root() / "static_10s_without_masks";
  fs::create_directories(copy);
  for (const fs::directory_entry& entry : fs::directory_iterator(original)) {
    if (entry.path().filename() == "masks") continue;
    fs::copy(entry.path(), copy / entry.path().filename(), fs::copy_options::recursive);
  }
  ASSERT_FALSE(fs::exists(copy / "masks"));
  const RunResult& with_masks = staticInertialRun();
  const RunResult without_masks = run(copy.string(), true);
  ASSERT_EQ(without_masks.trajectory.size(), with_masks.trajectory.size());
  for (std::size_t i = 0; i < with_masks.trajectory.size(); ++i) {
    ASSERT_EQ(without_masks.trajectory[i].t_s, with_masks.trajectory[i].t_s);
    ASSERT_EQ(without_masks.trajectory[i].T_w_c.translation(), with_masks.trajectory[i].T_w_c.translation())
        << "frame " << i;
    ASSERT_EQ(without_masks.trajectory[i].T_w_c.quaternion().coeffs(),
              with_masks.trajectory[i].T_w_c.quaternion().coeffs())
        << "frame " << i;
  }
  EXPECT_EQ(without_masks.counts.keyframes, with_masks.counts.keyframes);
  EXPECT_EQ(without_masks.counts.map_points, with_masks.counts.map_points);
}

// The --oracle-masks ablation on long-term large occlusion (boxes over most of the view): with
// perfect segmentation only static features are tracked and mapped, and the IMU carries the
// stretches with few of them. The floor the segmentation work is measured against.
TEST_F(VisualInertialEndToEnd, OracleMasksOnLongTermOcclusionStayWithinThreeCentimetres) {
  const RunResult oracle = run(sequence("ltlo_10s", sim::Scenario::kLtlo, 10.0, 1), true, true);
  EXPECT_GE(oracle.counts.frames_with_pose, oracle.frames - 5);  // boxes may cover the first frames
  EXPECT_TRUE(oracle.counts.imu_initialised);
  EXPECT_EQ(oracle.counts.maps - oracle.counts.merges, 1);
  EXPECT_LT(oracle.ate.error_m.rmse, 0.03);
}

}  // namespace
}  // namespace ltlo::system
