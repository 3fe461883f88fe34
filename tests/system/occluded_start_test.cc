// Occluded start end to end (issue 32), System on a short generated 320x240 sequence at 15 Hz,
// synchronous (deterministic): the ltlo scenario with a box covering 40-80 % of frame 0 that moves
// with the robot until it is pushed away (simulate --occluded-start away, seeds 1 and 2: 46 and
// 62 % of the view at VGA), with config_yaml/synthetic.yaml's occluded-start handling
// (Tracking.StartProvisional, Tracking.StartReacquireSpeed, Tracking.StartRecoveryCutsImu). The run
// must not take the box as the world: every frame has a pose and the first IMU initialisation's
// gravity is within 5 deg of the truth. A relocalised start keeps one world
// (Tracking.StartRecoveryGauge): no keyframe of the map is left in the world tracking had before;
// nor does a start that changes worlds without a loss (Tracking.StartMotionCheck).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "end_to_end_suite.h"
#include "ltlo/core/log.h"
#include "ltlo/core/settings.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/system/hindsight_masks.h"
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
/// With a still start, the box stands until it is pushed (seed 2).
constexpr double kBoxAtRestUntil_s = 1.5;

struct OccludedRun {
  int frames = 0;
  SystemCounts counts;
  double ate_online_m = 0.0;  ///< RMSE of the online poses after the SE3 alignment
  double ate_final_m = 0.0;   ///< of trajectory.txt's poses
  std::optional<double> gravity_error_deg;  ///< of the first IMU initialisation
  double worst_rotation_deg = 0.0;  ///< of the online poses relative to the first, against the truth's
};

double angleDeg(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI; }

/// The largest rotation error of `estimate`'s poses relative to its first, against the truth's
/// relative to the truth at the same time (nearest stamp), deg.
double worstRotationError_deg(const io::Trajectory& estimate, const io::Trajectory& truth) {
  if (estimate.empty()) return 0.0;
  const SE3 T_first_w = estimate.front().T_w_x.inverse();
  const SE3 T_first_w_true = test_support::truthNearest(truth, estimate.front().t_s).inverse();
  double worst_deg = 0.0;
  for (const io::StampedPose& pose : estimate) {
    const Mat3 R_estimated = (T_first_w * pose.T_w_x).rotationMatrix();
    const Mat3 R_true = (T_first_w_true * test_support::truthNearest(truth, pose.t_s)).rotationMatrix();
    worst_deg = std::max(worst_deg, so3Log(R_estimated.transpose() * R_true).norm() * 180.0 / M_PI);
  }
  return worst_deg;
}

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

  static OccludedRun run(std::uint64_t seed, sim::StartMove move,
                         const std::function<void(Settings&)>& configure = [](Settings&) {}) {
    const std::string dir = sequence(seed, move);
    Settings settings = shortRunSettings(dir);
    configure(settings);
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
    out.worst_rotation_deg = worstRotationError_deg(toTumTrajectory(system.onlineTrajectory()), truth);
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

TEST_F(OccludedStartEndToEnd, BeforeTheImuIsInitialisedNoPoseTurnsAwayFromTheGyroscope) {
  // Seed 2 with Seg.Clusters 64 (where the case shows): at 1.13 s, after the box held the view, the
  // frame is recovered on 43 inliers turned 14.5 deg from the gyroscope's rotation, and the online
  // poses keep that error (18-24 deg) to the end; the first IMU initialisation is 7.0 deg off.
  // Tracking.GyroRotationGate (5 deg) makes that frame lost: the rotation error stays within 2.1 deg
  // and the initialisation is 1.0 deg off.
  const auto configure = [](double gate_deg) {
    return [gate_deg](Settings& settings) {
      settings.segmentation.num_clusters = 64;
      settings.tracking.gyro_rotation_gate_deg = gate_deg;
    };
  };
  const OccludedRun off = run(2, sim::StartMove::kAway, configure(0.0));
  const OccludedRun on = run(2, sim::StartMove::kAway, configure(5.0));
  log::info("rotation error of the online poses: ", off.worst_rotation_deg, " deg without the gate, ",
            on.worst_rotation_deg, " deg with it");
  EXPECT_GT(off.worst_rotation_deg, 10.0) << "the case is gone: no pose turns away from the gyroscope without the gate";
  EXPECT_LT(on.worst_rotation_deg, 3.0);
  EXPECT_EQ(on.counts.frames_with_pose, on.frames);
  ASSERT_TRUE(on.gravity_error_deg.has_value());
  EXPECT_LT(*on.gravity_error_deg, 3.0);
}

/// The VGA 30 Hz sequence of 2 s, seed 3 (the box over 75 % of frame 0), written once per suite.
fs::path vgaSeed3Sequence(const fs::path& root) {
  const fs::path dir = root / "occluded_vga_s3";
  if (!fs::exists(dir / "calib.yaml")) {
    sim::SimOptions sim_options;
    sim_options.scenario = sim::Scenario::kLtlo;
    sim_options.seed = 3;
    sim_options.duration_s = 2.0;
    sim_options.occluded_start = sim::StartMove::kAway;
    sim::writeSequence(sim_options, dir.string(), 0);
  }
  return dir;
}

/// Runs config_yaml/synthetic.yaml (changed by `configure`) on `dir`; the worst keyframe's position
/// error relative to the first keyframe left in the map, m.
double worstStartKeyFrameError_m(const fs::path& dir, const std::shared_ptr<const bow::Vocabulary>& vocabulary,
                                 const std::function<void(Settings&)>& configure, const char* what) {
  Settings settings = Settings::load((test_support::sourceDir() / "config_yaml/synthetic.yaml").string(),
                                     (dir / "calib.yaml").string());
  configure(settings);
  io::SequenceReaderOptions reader_options;
  reader_options.calib_override = settings.calib;
  io::SequenceReader reader = io::SequenceReader::open(dir.string(), reader_options);
  SystemOptions options;
  options.threaded = false;
  System system(settings, vocabulary, options);
  int frames = 0;
  while (std::optional<io::RgbdImuFrame> input = reader.next()) {
    system.trackFrame(*input);
    ++frames;
  }
  system.shutdown();
  EXPECT_EQ(system.counts().frames_with_pose, frames) << what;
  const std::vector<KeyFrameRecord> keyframes = system.keyFrames();
  EXPECT_GE(keyframes.size(), 5u) << what;
  if (keyframes.empty()) return std::numeric_limits<double>::infinity();
  const double worst_m = worstKeyFrameRelativeError_m(keyframes, reader.groundTruth());
  log::info(what, ": ", keyframes.size(), " keyframes, the worst ", worst_m * 100.0, " cm off relative to the first");
  return worst_m;
}

TEST_F(OccludedStartEndToEnd, ARelocalisedStartLeavesNoKeyFrameInTheOtherWorld) {
  // VGA at 30 Hz, 2 s, seed 3 (the box over 75 % of frame 0): tracking follows the box for 0.3 s,
  // is lost, and relocalises at 0.37 s on kf1, made while it followed the box, whose points are
  // 12.8 cm off kf0's. Measured: kf0 stays 12.6 cm off every later keyframe with the switch off (at
  // 29 s of the 45 s run a proximity loop onto it pulls the map 12 cm, a false loop); with it on,
  // kf0 leaves the map and the worst keyframe is 0.7 cm off. Tracking.StartMotionCheck is off here:
  // it sees the same change at 0.33 s, a frame before the loss (the next test). Seg.Clusters 24 (DESIGN.md's
  // K): at the shipped 64 tracking is not lost there (the next test's case), so no relocalisation recovers.
  const fs::path dir = vgaSeed3Sequence(root());
  double worst_m[2] = {0.0, 0.0};
  for (const bool gauge : {false, true}) {
    worst_m[gauge] = worstStartKeyFrameError_m(
        dir, vocabulary(),
        [gauge](Settings& settings) {
          settings.segmentation.num_clusters = 24;
          settings.tracking.start_recovery_gauge = gauge;
          settings.tracking.start_motion_check_m_s2 = 0.0;
        },
        gauge ? "relocalised start, Tracking.StartRecoveryGauge 1" : "relocalised start, Tracking.StartRecoveryGauge 0");
  }
  EXPECT_GT(worst_m[0], 0.08) << "the switch off no longer leaves kf0 in the box's world: the test lost its case";
  EXPECT_LT(worst_m[1], 0.02);
}

TEST_F(OccludedStartEndToEnd, AStartThatChangesWorldsWithoutALossLeavesNoKeyFrameInTheOtherWorld) {
  // The same sequence with Seg.Clusters 64 (the shipped K): tracking follows the box for 0.27 s and then the room
  // without being lost, so no relocalisation recovers it; kf1 and kf2, made in between, stay 13.5 cm
  // off kf0. Tracking.StartMotionCheck: the window to 0.33 s gives gravity 4.9 m/s^2 off the first
  // window's (bound 3; position sigma 3 mm), kf2 becomes the gauge and the worst keyframe is 1.1 cm off.
  const fs::path dir = vgaSeed3Sequence(root());
  double worst_m[2] = {0.0, 0.0};
  for (const bool check : {false, true}) {
    worst_m[check] = worstStartKeyFrameError_m(
        dir, vocabulary(),
        [check](Settings& settings) {
          settings.segmentation.num_clusters = 64;
          settings.tracking.start_motion_check_m_s2 = check ? 3.0 : 0.0;
        },
        check ? "start changing worlds, Tracking.StartMotionCheck 3" : "start changing worlds, Tracking.StartMotionCheck 0");
  }
  EXPECT_GT(worst_m[0], 0.08) << "without the check the start no longer leaves kf0 in another world: the test lost its case";
  EXPECT_LT(worst_m[1], 0.02);
}

/// Static-background IoU of a mask against the ground truth's (255 = dynamic in both).
double staticIou(const cv::Mat& estimate, const cv::Mat& truth) {
  const cv::Mat both = (estimate == 0) & (truth == 0), either = (estimate == 0) | (truth == 0);
  const int union_px = cv::countNonZero(either);
  return union_px == 0 ? 1.0 : cv::countNonZero(both) / static_cast<double>(union_px);
}

TEST_F(OccludedStartEndToEnd, ABoxAtRestFromTheFirstFrameIsDynamicInHindsight) {
  // Robot and box at rest for the first 3 s (simulate --occluded-start away --still 0,3, seed 2):
  // nothing moves, and online the box is the world. Once pushed away, the wall behind it enters the
  // map, and the hindsight masks (segmentation_final/) call the box dynamic in the frames before.
  // Measured (320x240, 15 Hz, 8 s): static IoU before 1.5 s 0.382 online, 0.686 final with the map points'
  // votes alone, 0.915 with the keyframes' depth as free space too (Seg.HindsightFreeSpace: the floor
  // beside and behind the box, seen at a grazing angle, holds no map point but is seen in depth); over
  // the run 0.731, 0.853 and 0.946.
  const fs::path dir = root() / "still_away_s2";
  if (!fs::exists(dir / "groundtruth.txt")) {
    sim::SimOptions sim_options = shortRunSimOptions(sim::Scenario::kLtlo, 2, kSeconds);
    sim_options.occluded_start = sim::StartMove::kAway;
    sim_options.stills = {{0.0, 3.0}};
    sim::writeSequence(sim_options, dir.string(), 0);
  }
  const Settings settings = shortRunSettings(dir.string());
  io::SequenceReaderOptions reader_options;
  reader_options.calib_override = settings.calib;
  io::SequenceReader reader = io::SequenceReader::open(dir.string(), reader_options);
  const fs::path run_dir = root() / "still_away_s2_run";
  SystemOptions options;
  options.threaded = false;
  options.segmentation_dir = (run_dir / "segmentation").string();
  System system(settings, vocabulary(), options);
  int frames = 0;
  while (std::optional<io::RgbdImuFrame> input = reader.next()) {
    system.trackFrame(*input);
    ++frames;
  }
  system.shutdown();
  const RunReport report = system.report(0.0);

  io::SequenceReaderOptions masks_options = reader_options;
  masks_options.masks_dir = options.segmentation_dir;
  const io::SequenceReader masks = io::SequenceReader::open(dir.string(), masks_options);
  const HindsightMaskResult result =
      writeHindsightMasks(masks, report.trajectory, report.keyframes, report.map_points_map, report.map_points,
                          settings.calib.camera.model(), HindsightMaskOptions::from(settings),
                          (run_dir / "segmentation_final").string());
  EXPECT_EQ(result.frames_written, frames);
  EXPECT_EQ(result.frames_relabelled, report.counts.frames_with_pose);

  double online_rest = 0.0, final_rest = 0.0, online_all = 0.0, final_all = 0.0;
  int rest_frames = 0;
  for (int i = 0; i < frames; ++i) {
    const io::FrameFiles& files = reader.frameFiles(i);
    const std::string name = fs::path(masks.frameFiles(i).mask_path).filename().string();
    const cv::Mat truth = cv::imread((dir / "masks" / name).string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat online = cv::imread((run_dir / "segmentation" / name).string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat hindsight = cv::imread((run_dir / "segmentation_final" / name).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(truth.empty() || online.empty() || hindsight.empty()) << name;
    const double online_iou = staticIou(online, truth), final_iou = staticIou(hindsight, truth);
    online_all += online_iou;
    final_all += final_iou;
    if (files.t_s < kBoxAtRestUntil_s) {
      online_rest += online_iou;
      final_rest += final_iou;
      ++rest_frames;
    }
  }
  ASSERT_GT(rest_frames, 0);
  online_rest /= rest_frames;
  final_rest /= rest_frames;
  online_all /= frames;
  final_all /= frames;
  log::info("box at rest from frame 0: static IoU before ", kBoxAtRestUntil_s, " s online ", online_rest, ", final ",
            final_rest, "; over the run online ", online_all, ", final ", final_all, " (", result.frames_changed,
            " frames changed)");
  EXPECT_GT(final_rest, online_rest + 0.4);
  EXPECT_GT(final_all, online_all + 0.15);
}

}  // namespace
}  // namespace ltlo::system
