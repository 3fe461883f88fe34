// End to end under large occlusion (issue 12): System with the dynamic segmentation, robust VIBA
// and static-only loop closing on generated 16 s VGA sequences at 15 Hz where a box covers most
// of the view for most of the run. Each test asserts the number the project exists for, ATE RMSE
// <= 0.05 m against the ground truth (over all frames and over the occluded frames alone), and the
// segmentation against the sequence's masks: static IoU >= 0.9, and for the carried box a dynamic
// recall >= 0.9.
//
// The occlusion is checked from the ground-truth masks before anything else, so a change of the
// simulator's schedule cannot make the tests easy: the share of frames more than 40 % dynamic, the
// longest such stretch and the mean dynamic fraction over those frames must stay near what was
// measured when the tests were written (stated per test).
//
// Why VGA: at 320x240 the 16 s ltlo run drifts to 0.065-0.10 m ATE, 0.09 m even with the
// ground-truth masks (--oracle-masks), while a static 320x240 run stays at 5.5 mm (presumably too
// few and too coarse features on the third of the view left static; not investigated further).
// At 640x480 the same run stays near 1 cm, as the 45 s runs do. 16 s at 15 Hz leaves the IMU time
// to initialise (8 keyframes at 2 Hz, ~3.7 s) before the ltlo box arrives (4.3 s); a box that
// arrives before the initialisation is the open failure of ltlo seeds 2 and 3 at 45 s (issue 12),
// not tested here.
//
// Runs are synchronous (local mapping and loop closing inside trackFrame): deterministic, so the
// bounds do not depend on the machine's load. Measured when written (seeds 1-3, 16 s VGA 15 Hz):
//   ltlo    seed 1: ATE 0.0095 m, static IoU 0.974; seed 2: 0.0123 m, 0.958; seed 3 fails (box at
//           2.9 s, before the IMU initialisation: 3 maps, 0.28 m); Seg.Enable off, seed 1: 0.32 m.
//   carried seed 1: ATE 0.0067 m, IoU 0.991, recall 0.997; seeds 2, 3: 0.0030 / 0.0027 m, IoU
//           0.994 / 0.995; Seg.Enable off, seed 1: 1.13 m.
//   carried seed 1 with a plain box (issue 32): ATE 0.0082 m, IoU 0.991, recall 0.997.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <unordered_set>

#include "bow/vocabulary.h"
#include "end_to_end_suite.h"
#include "ltlo/core/log.h"
#include "ltlo/core/settings.h"
#include "ltlo/eval/mask_iou.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/system/run_outputs.h"
#include "ltlo/system/system.h"

namespace ltlo::system {
namespace {

namespace fs = std::filesystem;

using test_support::EndToEndSuite;
using test_support::sourceDir;

constexpr double kFps = 15.0;
constexpr double kSeconds = 16.0;
/// The acceptance bounds for the short end-to-end runs.
constexpr double kMaxAteM = 0.05;
constexpr double kMinStaticIou = 0.9;
constexpr double kMinDynamicRecall = 0.9;

/// How much of the view the boxes cover, from the sequence's ground-truth masks.
struct Occlusion {
  int frames = 0;
  int occluded_frames = 0;  ///< frames more than eval::kOccludedFraction (40 %) dynamic
  double occluded_share = 0.0;
  double longest_occluded_s = 0.0;      ///< longest run of consecutive occluded frames
  double mean_fraction_occluded = 0.0;  ///< mean dynamic fraction over the occluded frames
  std::unordered_set<long long> occluded_us;  ///< timestamps (microseconds) of the occluded frames
};

/// Logged under `name` (the scenario), so a failing run's log says how occluded it was.
Occlusion measureOcclusion(const std::string& dir, const std::string& name) {
  io::SequenceReaderOptions options;
  options.read_masks = true;  // only to find the mask files; no frame is decoded
  const io::SequenceReader reader = io::SequenceReader::open(dir, options);
  Occlusion occlusion;
  int run = 0, longest = 0;
  double fraction_sum = 0.0;
  for (int i = 0; i < reader.frameCount(); ++i) {
    const io::FrameFiles& files = reader.frameFiles(i);
    if (files.mask_path.empty()) ADD_FAILURE() << "no mask for frame " << i << " in " << dir;
    const cv::Mat mask = cv::imread(files.mask_path, cv::IMREAD_UNCHANGED);
    if (mask.type() != CV_8UC1) ADD_FAILURE() << files.mask_path << ": not an 8-bit mask";
    if (mask.type() != CV_8UC1) continue;
    const double fraction = static_cast<double>(cv::countNonZero(mask >= 128)) / static_cast<double>(mask.total());
    ++occlusion.frames;
    if (fraction > eval::kOccludedFraction) {
      ++occlusion.occluded_frames;
      fraction_sum += fraction;
      occlusion.occluded_us.insert(std::llround(files.t_s * 1e6));
      longest = std::max(longest, ++run);
    } else {
      run = 0;
    }
  }
  occlusion.occluded_share = occlusion.frames > 0 ? static_cast<double>(occlusion.occluded_frames) / occlusion.frames : 0.0;
  occlusion.longest_occluded_s = longest / kFps;
  occlusion.mean_fraction_occluded = occlusion.occluded_frames > 0 ? fraction_sum / occlusion.occluded_frames : 0.0;
  log::info("e2e occlusion ", name, ": ", occlusion.occluded_frames, "/", occlusion.frames, " frames occluded (",
            occlusion.occluded_share, "), longest ", occlusion.longest_occluded_s, " s, mean dynamic fraction ",
            occlusion.mean_fraction_occluded);
  return occlusion;
}

struct RunResult {
  int frames = 0;
  SystemCounts counts;
  double ate_rmse_m = 0.0;           ///< all frames with a pose, SE3-aligned
  double ate_occluded_rmse_m = 0.0;  ///< the occluded frames only, same alignment
  int occluded_matched = 0;          ///< occluded frames with a pose
  eval::MaskIouResult iou;           ///< the run's segmentation/ against masks/
};

class OcclusionEndToEnd : public EndToEndSuite {
 protected:
  static void SetUpTestSuite() { createSuiteResources("ltlo_occlusion_"); }
  static void TearDownTestSuite() { removeSuiteResources(); }

  /// The 16 s VGA sequence of `scenario` and `seed` at 15 Hz, with sensor noise.
  /// plain: every mover one plain colour (simulate --plain-movers).
  static std::string sequence(sim::Scenario scenario, std::uint64_t seed, bool plain = false) {
    const fs::path dir =
        root() / (sim::scenarioName(scenario) + (plain ? "_plain" : "") + "_seed" + std::to_string(seed));
    sim::SimOptions options;
    options.scenario = scenario;
    options.seed = seed;
    options.plain_movers = plain;
    options.duration_s = kSeconds;
    options.fps = kFps;
    sim::writeSequence(options, dir.string(), 0);
    return dir.string();
  }

  /// The shipped synthetic settings (segmentation, robust VIBA and the static loop gate on, as the
  /// YAML has them), with keyframes at least twice a second and the IMU initialised after 8 of them
  /// so that a 16 s run is inertial before the first box arrives.
  static Settings settingsFor(const std::string& dir) {
    Settings settings = Settings::load((sourceDir() / "config_yaml/synthetic.yaml").string(),
                                       (fs::path(dir) / "calib.yaml").string());
    settings.keyframe.max_interval_s = 0.5;
    settings.imu_init.min_keyframes = 8;
    settings.segmentation.enable = true;
    return settings;
  }

  static RunResult run(const std::string& dir, const Occlusion& occlusion) {
    const fs::path masks_dir = fs::path(dir + "_segmentation");
    io::SequenceReader reader = io::SequenceReader::open(dir);
    RunResult result;
    {
      SystemOptions options;
      options.use_imu = true;
      options.threaded = false;
      options.segmentation_dir = masks_dir.string();
      System system(settingsFor(dir), vocabulary(), options);
      while (std::optional<io::RgbdImuFrame> input = reader.next()) {
        system.trackFrame(*input);
        ++result.frames;
      }
      system.shutdown();  // also flushes the segmentation writer
      result.counts = system.report(1.0).counts;
      const eval::MatchedTrajectories matched =
          eval::associateTrajectories(reader.groundTruth(), toTumTrajectory(system.trajectory()));
      if (matched.est.size() >= 3) {
        const eval::AteResult ate = eval::computeAte(matched, false);
        result.ate_rmse_m = ate.error_m.rmse;
        double sum_sq = 0.0;
        for (std::size_t i = 0; i < matched.est.size(); ++i) {
          if (occlusion.occluded_us.count(std::llround(matched.gt[i].t_s * 1e6)) == 0) continue;
          const Vec3 p_est = ate.S_gt_est * matched.est[i].T_w_x.translation();
          sum_sq += (p_est - matched.gt[i].T_w_x.translation()).squaredNorm();
          ++result.occluded_matched;
        }
        if (result.occluded_matched > 0) result.ate_occluded_rmse_m = std::sqrt(sum_sq / result.occluded_matched);
      }
    }
    result.iou = eval::evaluateMaskFolders((fs::path(dir) / "masks").string(), masks_dir.string());
    log::info("e2e occlusion ", fs::path(dir).filename().string(), ": ATE rmse ", result.ate_rmse_m,
              " m (occluded frames ", result.ate_occluded_rmse_m, " m over ", result.occluded_matched,
              "), static IoU ", result.iou.mean_static_iou, " (occluded ", result.iou.mean_static_iou_occluded,
              "), dynamic recall ", result.iou.dynamic_recall, "; ", result.counts.frames_with_pose, "/",
              result.frames, " with a pose, ", result.counts.keyframes, " keyframes, ", result.counts.maps,
              " map(s), ", result.counts.loops, " loop(s), imu ", result.counts.imu_initialised);
    return result;
  }

  static void expectWholeRun(const RunResult& result, const Occlusion& occlusion) {
    EXPECT_EQ(result.counts.frames, result.frames);
    EXPECT_EQ(result.counts.frames_with_pose, result.frames);  // the boxes arrive after the first frames
    EXPECT_TRUE(result.counts.imu_initialised);
    EXPECT_EQ(result.counts.maps, 1);  // tracking was never lost for good
    EXPECT_EQ(result.counts.maps_created, 0);
    EXPECT_EQ(result.occluded_matched, occlusion.occluded_frames);
    EXPECT_EQ(result.iou.num_frames, result.frames);  // one segmentation mask per frame
  }

};


// Long-term large occlusion, seed 1: two pushed boxes (one behind the other, both swaying) cover
// more than 40 % of the view on 67.5 % of the frames, in one stretch of 10.8 s from t = 4.3 s to
// the end (mean dynamic fraction 65 % over those frames). Without the segmentation the run follows
// the boxes (0.32 m ATE); with it, the static remainder and the IMU carry the trajectory.
TEST_F(OcclusionEndToEnd, LongTermOcclusionKeepsTheTrajectoryAndSegmentsTheBoxes) {
  const std::string dir = sequence(sim::Scenario::kLtlo, 1);
  const Occlusion occlusion = measureOcclusion(dir, "ltlo");
  ASSERT_GE(occlusion.occluded_share, 0.6);
  ASSERT_GE(occlusion.longest_occluded_s, 9.0);
  ASSERT_GE(occlusion.mean_fraction_occluded, 0.55);

  const RunResult result = run(dir, occlusion);
  expectWholeRun(result, occlusion);
  EXPECT_LE(result.ate_rmse_m, kMaxAteM);
  EXPECT_LE(result.ate_occluded_rmse_m, kMaxAteM);
  EXPECT_GE(result.iou.mean_static_iou, kMinStaticIou);
  EXPECT_GE(result.iou.mean_static_iou_occluded, kMinStaticIou);
}

// A box carried in front of the robot (rigid to the body, so its image barely moves while the
// room flows past behind it) from 20 % to 85 % of the run, seed 1: more than 40 % of the view on 56 % of the frames, one stretch of 9.0 s (mean
// dynamic fraction 72 % over those frames). Features on the box would pin the camera to it
// (1.13 m ATE with Seg.Enable off); the segmentation must call the box dynamic on its frames.
TEST_F(OcclusionEndToEnd, CarriedBoxIsDynamicAndTheTrajectoryHolds) {
  const std::string dir = sequence(sim::Scenario::kCarried, 1);
  const Occlusion occlusion = measureOcclusion(dir, "carried");
  ASSERT_GE(occlusion.occluded_share, 0.5);
  ASSERT_GE(occlusion.longest_occluded_s, 8.0);
  ASSERT_GE(occlusion.mean_fraction_occluded, 0.6);

  const RunResult result = run(dir, occlusion);
  expectWholeRun(result, occlusion);
  EXPECT_LE(result.ate_rmse_m, kMaxAteM);
  EXPECT_LE(result.ate_occluded_rmse_m, kMaxAteM);
  EXPECT_GE(result.iou.dynamic_recall, kMinDynamicRecall);
  EXPECT_GE(result.iou.mean_static_iou, kMinStaticIou);
}

// The carried box of the test above in one plain colour (issue 32, texture-less movers): no
// texture for ORB or for the dense intensity residual, so the depth term and the IMU's motion
// prior must call it dynamic. Same schedule and occlusion as the textured box. Measured when
// written: ATE 8.2 mm (occluded frames 6.3), static IoU 0.991, recall 0.997: the labels are the
// textured box's to the last digit (the depth clusters and the IMU decide here; the box's texture
// moved only the tracking: 5.8 mm with it).
TEST_F(OcclusionEndToEnd, PlainCarriedBoxIsDynamicAndTheTrajectoryHolds) {
  const std::string dir = sequence(sim::Scenario::kCarried, 1, true);
  const Occlusion occlusion = measureOcclusion(dir, "carried plain");
  ASSERT_GE(occlusion.occluded_share, 0.5);
  ASSERT_GE(occlusion.longest_occluded_s, 8.0);
  ASSERT_GE(occlusion.mean_fraction_occluded, 0.6);

  const RunResult result = run(dir, occlusion);
  expectWholeRun(result, occlusion);
  EXPECT_LE(result.ate_rmse_m, kMaxAteM);
  EXPECT_LE(result.ate_occluded_rmse_m, kMaxAteM);
  EXPECT_GE(result.iou.dynamic_recall, kMinDynamicRecall);
  EXPECT_GE(result.iou.mean_static_iou, kMinStaticIou);
}

}  // namespace
}  // namespace ltlo::system
