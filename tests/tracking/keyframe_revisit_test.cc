// The keyframe decision on revisits (issue 32, KF.RevisitMaxInterval): a simulated static sequence
// is played forwards and then backwards, so the second pass sees only what the first one mapped.
// With the revisit rule the second pass makes half as many keyframes at most, none later than
// KF.RevisitMaxInterval after the last; without it, as many as the first pass (the interval rule).
// Tracking holds in both.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/map/atlas.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/tracking/frame_builder.h"
#include "ltlo/tracking/tracker.h"

namespace ltlo::tracking {
namespace {

namespace fs = std::filesystem;

/// One simulated static sequence for the file's tests (written once, removed at exit).
class KeyFramesOnRevisit : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() / ("ltlo_revisit_" + std::to_string(::getpid())));
    sim::SimOptions options;
    options.width_px = 320;
    options.height_px = 240;
    options.scenario = sim::Scenario::kStatic;
    options.seed = 5;
    options.duration_s = 4.0;
    sim::writeSequence(options, dir_->string(), 0);
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }

  struct PassResult {
    int frames = 0;
    int tracked = 0;
    int keyframes = 0;
    double longest_gap_s = 0.0;  ///< between consecutive keyframes of the pass
    eval::AteResult ate;
  };
  struct RevisitResult {
    PassResult forwards;
    PassResult backwards;
    int deferred = 0;  ///< frames whose keyframe the revisit rule deferred
  };

  /// The sequence forwards, its last frame once more (the motion model stops), then backwards with
  /// timestamps going on (t' = 2 t_end - t); vision only, the first pose from ground truth.
  static RevisitResult run(double revisit_max_interval_s) {
    io::SequenceReader reader = io::SequenceReader::open(dir_->string());
    OrbOptions orb;
    orb.num_features = 500;
    const FrameBuilder builder(orb, reader.calib());
    std::vector<io::RgbdImuFrame> inputs;
    while (auto input = reader.next()) {
      input->imu.clear();  // played backwards the IMU would contradict the images
      inputs.push_back(std::move(*input));
    }
    map::Atlas atlas(1);
    TrackerOptions options;
    // The first pass maps the place densely (a keyframe every 0.25 s), as laps of a room leave it:
    // its points are seen by three keyframes and more.
    options.keyframe.max_interval_s = 0.25;
    options.keyframe.revisit_max_interval_s = revisit_max_interval_s;
    // Without local mapping (no fusion of duplicates) the points a pass makes keep fewer observers
    // than in the system, so the second pass's mapped share is 0.64-0.75 (the first pass 0.28-0.59),
    // and its unmapped share 0-2 % (the first pass 8-27 %).
    options.keyframe.revisit_mapped_share = 0.6;
    options.keyframe.revisit_max_new_share = 0.05;
    Tracker tracker(atlas, options, builder.extractor().levelSigma2());
    std::vector<double> keyframe_t_s;
    tracker.setLocalMappingCallback(
        [&](map::Map&, const std::shared_ptr<map::KeyFrame>& kf) { keyframe_t_s.push_back(kf->t_s()); });
    const double t_end_s = inputs.back().t_s;
    const double frame_s = inputs[1].t_s - inputs[0].t_s;
    RevisitResult result;
    auto play = [&](io::RgbdImuFrame input, double t_s, const SE3& T_w_c_true, PassResult* pass,
                    io::Trajectory* estimate, io::Trajectory* truth) {
      input.t_s = input.depth_t_s = t_s;
      map::Frame frame = builder.build(input);
      if (result.forwards.frames == 0) frame.setPose_T_w_c(T_w_c_true);
      const int keyframes_before = tracker.numKeyFrames();
      ++pass->frames;
      if (tracker.track(frame) == TrackingState::kOk) {
        ++pass->tracked;
        estimate->push_back({t_s, tracker.T_w_c()});
        truth->push_back({t_s, T_w_c_true});
      }
      pass->keyframes += tracker.numKeyFrames() - keyframes_before;
    };
    const io::Trajectory& ground_truth = reader.groundTruth();
    auto true_pose = [&](double t_s) {
      const auto it = std::min_element(ground_truth.begin(), ground_truth.end(), [&](const auto& a, const auto& b) {
        return std::abs(a.t_s - t_s) < std::abs(b.t_s - t_s);
      });
      return it->T_w_x;
    };
    io::Trajectory estimate, truth;
    for (const io::RgbdImuFrame& input : inputs) {
      play(input, input.t_s, true_pose(input.t_s), &result.forwards, &estimate, &truth);
    }
    result.forwards.ate = eval::computeAte(eval::associateTrajectories(truth, estimate), false);
    const std::size_t first_pass_keyframes = keyframe_t_s.size();
    estimate.clear();
    truth.clear();
    play(inputs.back(), t_end_s + frame_s, true_pose(t_end_s), &result.backwards, &estimate, &truth);
    for (std::size_t k = inputs.size() - 1; k-- > 0;) {
      const double t_s = 2.0 * t_end_s + frame_s - inputs[k].t_s;
      // Truth at the frame's original time, stamped with the new one.
      play(inputs[k], t_s, true_pose(inputs[k].t_s), &result.backwards, &estimate, &truth);
    }
    result.backwards.ate = eval::computeAte(eval::associateTrajectories(truth, estimate), false);
    for (std::size_t k = first_pass_keyframes; k < keyframe_t_s.size(); ++k) {
      result.backwards.longest_gap_s = std::max(result.backwards.longest_gap_s, keyframe_t_s[k] - keyframe_t_s[k - 1]);
    }
    result.deferred = tracker.numKeyFramesDeferredOnRevisit();
    return result;
  }
  static fs::path* dir_;
};
fs::path* KeyFramesOnRevisit::dir_ = nullptr;

TEST_F(KeyFramesOnRevisit, ASecondPassOverMappedGroundMakesHalfTheKeyFramesAtMost) {
  constexpr double kRevisitInterval_s = 2.0;
  const RevisitResult off = run(0.0);
  const RevisitResult on = run(kRevisitInterval_s);
  std::printf("keyframes forwards / backwards: %d / %d without the revisit rule, %d / %d with %.1f s (%d frames "
              "deferred, longest gap %.2f s); ATE backwards %.4f / %.4f m\n",
              off.forwards.keyframes, off.backwards.keyframes, on.forwards.keyframes, on.backwards.keyframes,
              kRevisitInterval_s, on.deferred, on.backwards.longest_gap_s, off.backwards.ate.error_m.rmse, on.backwards.ate.error_m.rmse);
  // Both runs track every frame of both passes.
  EXPECT_EQ(off.forwards.tracked, off.forwards.frames);
  EXPECT_EQ(off.backwards.tracked, off.backwards.frames);
  EXPECT_EQ(on.forwards.tracked, on.forwards.frames);
  EXPECT_EQ(on.backwards.tracked, on.backwards.frames);
  // Without the rule the revisit costs about as many keyframes as the first visit (the test fails
  // without the rule: its second pass is the `off` one).
  ASSERT_GE(off.backwards.keyframes, off.forwards.keyframes / 2);
  // With it, less than half as many; the rest come where the first pass's last keyframes alone
  // saw the view (its points have fewer than three observers). None is deferred past the interval.
  EXPECT_LE(on.backwards.keyframes, off.backwards.keyframes / 2);
  EXPECT_LE(on.backwards.longest_gap_s, kRevisitInterval_s + 1.5 / 30.0);
  EXPECT_GT(on.deferred, 0);
  // The first pass is untouched (nothing is mapped before it), and tracking over the mapped ground
  // stays as accurate (no BA: the error is the tracker's own, mm to a cm).
  EXPECT_EQ(on.forwards.keyframes, off.forwards.keyframes);
  EXPECT_LT(on.backwards.ate.error_m.rmse, std::max(0.02, 1.5 * off.backwards.ate.error_m.rmse));
}

}  // namespace
}  // namespace ltlo::tracking
