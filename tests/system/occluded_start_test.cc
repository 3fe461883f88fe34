// Occluded start end to end (issue 32), System on a short generated 320x240 sequence at 15 Hz,
// synchronous (deterministic): the ltlo scenario with a box covering 40-80 % of frame 0 that moves
// with the robot until it is pushed away (simulate --occluded-start away, seeds 1 and 2: 46 and
// 62 % of the view at VGA), with config_yaml/synthetic.yaml's occluded-start handling
// (Tracking.StartProvisional, Tracking.StartReacquireSpeed, Tracking.StartRecoveryCutsImu). The run
// must not take the box as the world: every frame has a pose and the first IMU initialisation's
// gravity is within 5 deg of the truth. A relocalised start keeps one world
// (Tracking.StartRecoveryGauge): no keyframe of the map is left in the world tracking had before.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <vector>

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
using test_support::truthNearest;

/// Seconds simulated: the box has left the view by 5 s; the IMU initialises at about 4 s.
constexpr double kSeconds = 8.0;

struct OccludedRun {
  int frames = 0;
  SystemCounts counts;
  double ate_online_m = 0.0;  ///< RMSE of the online poses after the SE3 alignment
  double ate_final_m = 0.0;   ///< of trajectory.txt's poses
  std::optional<double> gravity_error_deg;  ///< of the first IMU initialisation
};

double angleDeg(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI; }

class OccludedStartEndToEnd : public EndToEndSuite {
 public:
  static void SetUpTestSuite() { createSuiteResources("ltlo_occluded_start_"); }
  static void TearDownTestSuite() { removeSuiteResources(); }

  static std::string sequence(std::uint64_t seed, sim::StartMove move) {
    const fs::path dir = root() / ("occluded_" + std::to_string(static_cast<int>(move)) + "_s" + std::to_string(seed));
    if (!fs::exists(dir / "groundtruth.txt")) {
      sim::SimOptions options = shortRunSimOptions(sim::Scenario::kLtlo, seed, kSeconds);
      options.occluded_start = move;
      sim::writeSequence(options, dir.string(), 0);
    }
    return dir.string();
  }

  static OccludedRun run(std::uint64_t seed, sim::StartMove move) {
    const std::string dir = sequence(seed, move);
    const Settings settings = shortRunSettings(dir);
    io::SequenceReaderOptions reader_options;
    reader_options.calib_override = settings.calib;
    io::SequenceReader reader = io::SequenceReader::open(dir, reader_options);
    SystemOptions options;
    options.threaded = false;
    System system(settings, vocabulary(), options);
    OccludedRun out;
    while (std::optional<io::RgbdImuFrame> input = reader.next()) {
      system.trackFrame(*input);
      ++out.frames;
      if (!out.gravity_error_deg && system.imuState().initialised) {
        // The map's world is the first frame's body: the true gravity there is R_w_b(0)^T (0, 0, -9.81).
        const io::Trajectory& truth = reader.groundTruth();
        const Mat3 R_w_b0 =
            truth.front().T_w_x.rotationMatrix() * sim::SimOptions::T_b_c().rotationMatrix().transpose();
        out.gravity_error_deg = angleDeg(system.imuState().g_w, R_w_b0.transpose() * Vec3(0.0, 0.0, -9.81));
      }
    }
    system.shutdown();
    out.counts = system.counts();
    const io::Trajectory& truth = reader.groundTruth();
    out.ate_online_m =
        eval::computeAte(eval::associateTrajectories(truth, toTumTrajectory(system.onlineTrajectory())), false)
            .error_m.rmse;
    out.ate_final_m =
        eval::computeAte(eval::associateTrajectories(truth, toTumTrajectory(system.trajectory())), false).error_m.rmse;
    log::info("occluded start, seed ", seed, ": ATE online ", out.ate_online_m * 1000.0,
              " mm, final ", out.ate_final_m * 1000.0, " mm, ", out.counts.frames_with_pose, "/", out.frames,
              " frames with a pose, ", out.counts.maps, " map(s), gravity ", out.gravity_error_deg.value_or(-1.0),
              " deg off");
    return out;
  }
};

TEST_F(OccludedStartEndToEnd, TheImuIsNotInitialisedOnTheBox) {
  // Measured (8 s, 320x240 at 15 Hz): gravity 3.3 deg (seed 1) and 1.7 deg (seed 2) off with the
  // method, 24.9 and 16.8 deg without it (the box's motion taken as the world's). At this resolution
  // tracking is lost again behind the box after the re-acquisition and a new map starts (2-3 maps
  // in 8 s, VGA keeps one), so the trajectory is not asserted here; docs/results.md has the VGA runs.
  for (const std::uint64_t seed : {1u, 2u}) {
    const OccludedRun on = run(seed, sim::StartMove::kAway);
    EXPECT_EQ(on.counts.frames_with_pose, on.frames) << "seed " << seed;
    ASSERT_TRUE(on.gravity_error_deg.has_value()) << "seed " << seed << ": the IMU did not initialise within "
                                                  << kSeconds << " s";
    EXPECT_LT(*on.gravity_error_deg, 5.0) << "seed " << seed;
  }
}

/// The largest translation error, m, of the keyframes' poses relative to the map's first remaining
/// keyframe against the same relative poses of the truth (nearest ground-truth instant).
double worstKeyFrameRelativeError_m(const std::vector<KeyFrameRecord>& keyframes, const io::Trajectory& truth) {
  const KeyFrameRecord* first = &keyframes.front();
  for (const KeyFrameRecord& kf : keyframes) {
    if (kf.t_s < first->t_s) first = &kf;
  }
  const SE3 T_first_w = first->T_w_c.inverse();
  const SE3 T_first_w_true = truthNearest(truth, first->t_s).inverse();
  double worst_m = 0.0;
  for (const KeyFrameRecord& kf : keyframes) {
    const SE3 estimated = T_first_w * kf.T_w_c;
    const SE3 true_relative = T_first_w_true * truthNearest(truth, kf.t_s);
    worst_m = std::max(worst_m, (true_relative.inverse() * estimated).translation().norm());
  }
  return worst_m;
}

TEST_F(OccludedStartEndToEnd, ARelocalisedStartLeavesNoKeyFrameInTheOtherWorld) {
  // VGA at 30 Hz, 2 s, seed 3 (the box over 75 % of frame 0): tracking follows the box for 0.3 s,
  // is lost, and relocalises at 0.37 s on kf1, made while it followed the box, whose points are
  // 12.8 cm off kf0's. Measured: kf0 stays 12.4 cm off every later keyframe with the switch off (at
  // 29 s of the 45 s run a proximity loop onto it pulls the map 12 cm, a false loop); with it on,
  // kf0 leaves the map and the worst keyframe is 0.5 cm off.
  const fs::path dir = root() / "occluded_vga_s3";
  sim::SimOptions sim_options;
  sim_options.scenario = sim::Scenario::kLtlo;
  sim_options.seed = 3;
  sim_options.duration_s = 2.0;
  sim_options.occluded_start = sim::StartMove::kAway;
  sim::writeSequence(sim_options, dir.string(), 0);
  double worst_m[2] = {0.0, 0.0};
  for (const bool gauge : {false, true}) {
    Settings settings = Settings::load((test_support::sourceDir() / "config_yaml/synthetic.yaml").string(),
                                       (dir / "calib.yaml").string());
    settings.tracking.start_recovery_gauge = gauge;
    io::SequenceReaderOptions reader_options;
    reader_options.calib_override = settings.calib;
    io::SequenceReader reader = io::SequenceReader::open(dir.string(), reader_options);
    SystemOptions options;
    options.threaded = false;
    System system(settings, vocabulary(), options);
    int frames = 0;
    while (std::optional<io::RgbdImuFrame> input = reader.next()) {
      system.trackFrame(*input);
      ++frames;
    }
    system.shutdown();
    EXPECT_EQ(system.counts().frames_with_pose, frames) << "gauge " << gauge;
    const std::vector<KeyFrameRecord> keyframes = system.keyFrames();
    ASSERT_GE(keyframes.size(), 5u) << "gauge " << gauge;
    worst_m[gauge] = worstKeyFrameRelativeError_m(keyframes, reader.groundTruth());
    log::info("relocalised start, Tracking.StartRecoveryGauge ", gauge, ": ", keyframes.size(),
              " keyframes, the worst ", worst_m[gauge] * 100.0, " cm off relative to the first");
  }
  EXPECT_GT(worst_m[0], 0.08) << "the switch off no longer leaves kf0 in the box's world: the test lost its case";
  EXPECT_LT(worst_m[1], 0.02);
}

}  // namespace
}  // namespace ltlo::system
