// Tracking front end on simulated static sequences (issue 6): visual odometry tracks every frame,
// the trajectory stays close to ground truth without BA, keyframes come at a sensible rate, the
// local-mapping callback runs once per keyframe, and black frames make the tracker lost (no crash).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <utility>
#include <vector>
#include <opencv2/core.hpp>

#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/map.h"
#include "ltlo/optim/bundle_adjust.h"
#include "ltlo/sim/simulator.h"
#include "ltlo/tracking/frame_builder.h"
#include "ltlo/tracking/tracker.h"

namespace ltlo::tracking {
namespace {

namespace fs = std::filesystem;

/// One simulated static sequence shared by the tests of this file (written once, removed at exit).
class TrackerOnSimulatedSequence : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() / ("ltlo_tracking_" + std::to_string(::getpid())));
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
  static OrbOptions orbOptions() {
    OrbOptions orb;
    orb.num_features = 500;
    return orb;
  }
  /// Runs the tracker over the whole sequence (the first pose from ground truth); returns ATE.
  struct RunResult {
    int frames = 0;
    int ok = 0;
    int keyframes = 0;
    int min_inliers = 1 << 30;
    double duration_s = 0.0;
    eval::AteResult ate;
  };
  static RunResult run(const Tracker::LocalMappingCallback& callback) {
    io::SequenceReader reader = io::SequenceReader::open(dir_->string());
    const FrameBuilder builder(orbOptions(), reader.calib());
    map::Atlas atlas(1);
    Tracker tracker(atlas, TrackerOptions(), builder.extractor().levelSigma2());
    tracker.setLocalMappingCallback(callback);
    RunResult result;
    io::Trajectory estimate;
    while (auto input = reader.next()) {
      map::Frame frame = builder.build(*input);
      if (result.frames == 0) frame.setPose_T_w_c(reader.groundTruth().front().T_w_x);
      const TrackingState state = tracker.track(frame);
      ++result.frames;
      if (state != TrackingState::kOk) continue;
      ++result.ok;
      estimate.push_back({frame.t_s(), tracker.T_w_c()});
      if (result.frames > 1) result.min_inliers = std::min(result.min_inliers, tracker.stats().inliers);
    }
    result.keyframes = tracker.numKeyFrames();
    result.duration_s = reader.frameTime(result.frames - 1) - reader.frameTime(0);
    result.ate = eval::computeAte(eval::associateTrajectories(reader.groundTruth(), estimate), false);
    return result;
  }
  static fs::path* dir_;
};

/// Visual local BA over the newest keyframes (the rest and the first keyframe fixed), written back
/// into the map: the synchronous stand-in for the local-mapping thread.
void localBundleAdjustNewest(map::Map& map, const std::shared_ptr<map::KeyFrame>& newest, int window) {
  optim::LocalBaProblem problem;
  problem.model.camera = newest->camera();
  problem.model.T_c_x = newest->T_b_c().inverse();
  problem.model.bf_px_m = newest->camera().fx() * TrackerOptions().tracking.virtual_baseline_m;
  const auto keyframes = map.keyFrames();  // by id
  const int n = static_cast<int>(keyframes.size());
  std::map<std::uint64_t, std::shared_ptr<map::KeyFrame>> in_problem;
  for (int k = 0; k < n; ++k) {
    optim::BaKeyFrame kf;
    kf.id = static_cast<int>(keyframes[static_cast<std::size_t>(k)]->id().value);
    kf.T_w_b = keyframes[static_cast<std::size_t>(k)]->T_w_b();
    kf.fixed = k == 0 || k < n - window;
    problem.keyframes.push_back(kf);
    in_problem[keyframes[static_cast<std::size_t>(k)]->id().value] = keyframes[static_cast<std::size_t>(k)];
  }
  const auto points = map.mapPoints();
  for (const auto& point : points) {
    problem.points.push_back({static_cast<int>(point->id().value), point->p_w()});
    for (const auto& [kf_id, index] : point->observations()) {
      const auto& kf = in_problem.at(kf_id.value);
      optim::BaObservation obs;
      obs.keyframe_id = static_cast<int>(kf_id.value);
      obs.point_id = static_cast<int>(point->id().value);
      const features::Keypoint& kp = kf->keypoints()[static_cast<std::size_t>(index)];
      obs.uv = Vec2(kp.x_px, kp.y_px);
      obs.depth_m = kf->depth_m(index);
      obs.sigma_px = kf->scaleFactors()[static_cast<std::size_t>(kp.octave)];
      problem.observations.push_back(obs);
    }
  }
  const optim::LocalBaResult result = optim::localBundleAdjust(problem);
  for (std::size_t k = 0; k < result.keyframes.size(); ++k) {
    if (!problem.keyframes[k].fixed) keyframes[k]->setPose_T_w_b(result.keyframes[k].T_w_b);
  }
  for (std::size_t k = 0; k < result.points.size(); ++k) points[k]->setPosition(result.points[k].p_w);
}
fs::path* TrackerOnSimulatedSequence::dir_ = nullptr;

TEST_F(TrackerOnSimulatedSequence, VisualOdometryTracksEveryFrameWithinCentimetres) {
  io::SequenceReader reader = io::SequenceReader::open(dir_->string());
  ASSERT_TRUE(reader.hasGroundTruth());
  const FrameBuilder builder(orbOptions(), reader.calib());
  map::Atlas atlas(1);
  map::Map& map = atlas.activeMap();
  Tracker tracker(atlas, TrackerOptions(), builder.extractor().levelSigma2());
  int callbacks = 0;
  tracker.setLocalMappingCallback([&](map::Map& m, const std::shared_ptr<map::KeyFrame>& kf) {
    ++callbacks;
    EXPECT_NE(m.keyFrame(kf->id()), nullptr);
  });

  // Start the estimate at the ground-truth first pose so the ATE alignment is nearly identity.
  io::Trajectory estimate;
  int frames = 0, ok = 0, min_inliers = 1 << 30;
  while (auto input = reader.next()) {
    map::Frame frame = builder.build(*input);
    if (frames == 0) frame.setPose_T_w_c(reader.groundTruth().front().T_w_x);
    const TrackingState state = tracker.track(frame);
    ++frames;
    if (state == TrackingState::kOk) {
      ++ok;
      estimate.push_back({frame.t_s(), tracker.T_w_c()});
      if (frames > 1) min_inliers = std::min(min_inliers, tracker.stats().inliers);
    }
  }
  const double duration_s = reader.frameTime(frames - 1) - reader.frameTime(0);
  const eval::AteResult ate =
      eval::computeAte(eval::associateTrajectories(reader.groundTruth(), estimate), false);
  const double keyframes_per_s = tracker.numKeyFrames() / duration_s;
  std::printf("frames %d ok %d keyframes %d (%.2f /s) points %zu min inliers %d ATE rmse %.4f m max %.4f m\n",
              frames, ok, tracker.numKeyFrames(), keyframes_per_s, map.numMapPoints(), min_inliers,
              ate.error_m.rmse, ate.error_m.max);

  EXPECT_EQ(ok, frames);  // initialised on frame 0, never lost
  // Lost is < 30 inliers; seeds 1, 2, 3, 5, 7 gave a minimum of 45-76 (500 features at 320x240).
  EXPECT_GE(min_inliers, 40);
  EXPECT_EQ(callbacks, tracker.numKeyFrames());
  EXPECT_EQ(static_cast<int>(map.numKeyFrames()), tracker.numKeyFrames());
  // At least one keyframe per KF.MaxInterval (1 s), but far fewer than one per frame.
  EXPECT_GE(keyframes_per_s, 1.0);
  EXPECT_LE(keyframes_per_s, 10.0);
  // Without BA, seeds 1, 2, 3, 5, 7 measured ATE rmse 6.4-13.2 mm (max error 15-29 mm) over the
  // ~1.7 m path of 4 s; the bound leaves ~4x the worst rmse for other platforms' floating point.
  EXPECT_LT(ate.error_m.rmse, 0.05);
  EXPECT_LT(ate.error_m.max, 0.10);
}

TEST_F(TrackerOnSimulatedSequence, LocalBundleAdjustmentInTheCallbackKeepsTracking) {
  const RunResult vo = run(nullptr);
  int calls = 0;
  const RunResult ba = run([&](map::Map& map, const std::shared_ptr<map::KeyFrame>& kf) {
    ++calls;
    localBundleAdjustNewest(map, kf, 5);
  });
  std::printf("VO: ATE rmse %.4f m, max %.4f m; with local BA: ATE rmse %.4f m, max %.4f m, %d keyframes\n",
              vo.ate.error_m.rmse, vo.ate.error_m.max, ba.ate.error_m.rmse, ba.ate.error_m.max, ba.keyframes);
  EXPECT_EQ(calls, ba.keyframes);
  EXPECT_EQ(ba.ok, ba.frames);
  EXPECT_LT(ba.ate.error_m.rmse, 0.05);
}

TEST_F(TrackerOnSimulatedSequence, ImuHookPredictsWithPreintegrationAfterInitialisation) {
  io::SequenceReader reader = io::SequenceReader::open(dir_->string());
  ASSERT_TRUE(reader.calib().has_imu);
  const FrameBuilder builder(orbOptions(), reader.calib());
  map::Atlas atlas(1);
  Tracker tracker(atlas, TrackerOptions(), builder.extractor().levelSigma2());
  io::Trajectory estimate;
  int frames = 0, ok = 0, imu_frames = 0;
  while (auto input = reader.next()) {
    // The world is the simulator's gravity-aligned one (first pose from ground truth); the IMU is
    // switched on after 10 vision-only frames have given a velocity, biases left at zero.
    if (frames == 10) tracker.setImuInitialised(imu::ImuBias(), imu::gravityWorld());
    map::Frame frame = builder.build(*input, tracker.bias());
    if (frames == 0) frame.setPose_T_w_c(reader.groundTruth().front().T_w_x);
    EXPECT_EQ(frame.imu_from_last_frame.has_value(), frames > 0) << "frame " << frames;
    const TrackingState state = tracker.track(frame);
    ++frames;
    if (state != TrackingState::kOk) continue;
    ++ok;
    if (tracker.stats().used_imu) ++imu_frames;
    estimate.push_back({frame.t_s(), tracker.T_w_c()});
  }
  const eval::AteResult ate =
      eval::computeAte(eval::associateTrajectories(reader.groundTruth(), estimate), false);
  std::printf("IMU-predicted frames %d of %d, ok %d, ATE rmse %.4f m max %.4f m\n", imu_frames, frames, ok,
              ate.error_m.rmse, ate.error_m.max);
  EXPECT_EQ(ok, frames);
  EXPECT_EQ(imu_frames, frames - 10);
  EXPECT_LT(ate.error_m.rmse, 0.05);
}

/// Longest gap (s) between consecutive keyframes made before `imu_init_t_s` and after it, with
/// TrackerOptions::imu_init_keyframe_interval_s = `interval_s` (the IMU set initialised at
/// `imu_init_t_s`).
std::pair<double, double> keyFrameGaps(const fs::path& dir, const OrbOptions& orb, double interval_s,
                                       double imu_init_t_s) {
  io::SequenceReader reader = io::SequenceReader::open(dir.string());
  const FrameBuilder builder(orb, reader.calib());
  map::Atlas atlas(1);
  TrackerOptions options;
  options.imu_init_keyframe_interval_s = interval_s;
  Tracker tracker(atlas, options, builder.extractor().levelSigma2());
  std::vector<double> keyframe_t_s;
  tracker.setLocalMappingCallback(
      [&](map::Map&, const std::shared_ptr<map::KeyFrame>& kf) { keyframe_t_s.push_back(kf->t_s()); });
  int frames = 0;
  while (auto input = reader.next()) {
    if (!tracker.imuInitialised() && input->t_s >= imu_init_t_s) {
      tracker.setImuInitialised(imu::ImuBias(), imu::gravityWorld());
    }
    map::Frame frame = builder.build(*input, tracker.bias());
    if (frames++ == 0) frame.setPose_T_w_c(reader.groundTruth().front().T_w_x);
    EXPECT_EQ(tracker.track(frame), TrackingState::kOk) << "t = " << frame.t_s();
  }
  double before_s = 0.0, after_s = 0.0;
  for (std::size_t k = 1; k < keyframe_t_s.size(); ++k) {
    double& gap = keyframe_t_s[k] <= imu_init_t_s ? before_s : after_s;
    gap = std::max(gap, keyframe_t_s[k] - keyframe_t_s[k - 1]);
  }
  return {before_s, after_s};
}

// Before the IMU is initialised a keyframe comes at least every imu_init_keyframe_interval_s (System
// sets ImuInit.MinTime / (MinKeyFrames - 1)), so the initialisation can run once MinTime is
// covered; afterwards only the KF.* rules apply. Without the option, the same frames leave longer
// gaps before the initialisation (the test can fail).
TEST_F(TrackerOnSimulatedSequence, KeyFramesComeEveryImuInitIntervalUntilTheImuIsInitialised) {
  constexpr double kInterval = 0.2, kImuInit = 2.5;
  const double frame_s = 1.0 / 30.0;  // the simulator's default rate
  const auto [plain_before_s, plain_after_s] = keyFrameGaps(*dir_, orbOptions(), 0.0, kImuInit);
  const auto [early_before_s, early_after_s] = keyFrameGaps(*dir_, orbOptions(), kInterval, kImuInit);
  std::printf("longest keyframe gap before / after the IMU initialisation: %.3f / %.3f s without, %.3f / %.3f s "
              "with a %.2f s interval\n",
              plain_before_s, plain_after_s, early_before_s, early_after_s, kInterval);
  ASSERT_GT(plain_before_s, kInterval + 1.5 * frame_s);  // the KF.* rules alone leave longer gaps
  EXPECT_LE(early_before_s, kInterval + 1.5 * frame_s);  // a keyframe the first frame past the interval
  EXPECT_GT(early_after_s, kInterval + 1.5 * frame_s);   // after the initialisation: KF.* alone again
}

/// Keyframe times (s) of a run in which every frame is weak (KF.MinTrackedPoints above any
/// frame's inliers) and no other rule fires, with KF.WeakMinInterval = `weak_min_interval_s`;
/// `tracked` counts the frames tracked.
std::vector<double> weakKeyFrameTimes(const fs::path& dir, const OrbOptions& orb, double weak_min_interval_s,
                                      int& frames, int& tracked) {
  io::SequenceReader reader = io::SequenceReader::open(dir.string());
  const FrameBuilder builder(orb, reader.calib());
  map::Atlas atlas(1);
  TrackerOptions options;
  options.keyframe.min_tracked_points = 10000;  // every frame is weak
  options.keyframe.max_overlap = 0.05;          // the overlap rule stays silent
  options.keyframe.max_interval_s = 100.0;      // so does the interval rule
  options.keyframe.weak_min_interval_s = weak_min_interval_s;
  Tracker tracker(atlas, options, builder.extractor().levelSigma2());
  std::vector<double> keyframe_t_s;
  tracker.setLocalMappingCallback(
      [&](map::Map&, const std::shared_ptr<map::KeyFrame>& kf) { keyframe_t_s.push_back(kf->t_s()); });
  frames = tracked = 0;
  while (auto input = reader.next()) {
    map::Frame frame = builder.build(*input);
    if (frames++ == 0) frame.setPose_T_w_c(reader.groundTruth().front().T_w_x);
    if (tracker.track(frame) == TrackingState::kOk) ++tracked;
  }
  return keyframe_t_s;
}

// A weak frame (fewer inliers than KF.MinTrackedPoints) becomes a keyframe only KF.WeakMinInterval
// after the last one: beside a large occluder the static strip never holds enough points, and a
// keyframe per frame would abort every local BA. With the interval 0 every weak frame is one (the
// test can fail both ways).
TEST_F(TrackerOnSimulatedSequence, AWeakViewMakesAKeyFrameEveryWeakIntervalNotEveryFrame) {
  constexpr double kWeakInterval = 0.1;
  const double frame_s = 1.0 / 30.0;  // the simulator's default rate
  int frames = 0, tracked = 0;
  const std::vector<double> every = weakKeyFrameTimes(*dir_, orbOptions(), 0.0, frames, tracked);
  EXPECT_EQ(tracked, frames);
  EXPECT_EQ(static_cast<int>(every.size()), frames);  // the first frame and then every weak frame
  const std::vector<double> spaced = weakKeyFrameTimes(*dir_, orbOptions(), kWeakInterval, frames, tracked);
  EXPECT_EQ(tracked, frames);
  ASSERT_GE(spaced.size(), 2u);
  double shortest_s = 1e9, longest_s = 0.0;
  for (std::size_t k = 1; k < spaced.size(); ++k) {
    shortest_s = std::min(shortest_s, spaced[k] - spaced[k - 1]);
    longest_s = std::max(longest_s, spaced[k] - spaced[k - 1]);
  }
  std::printf("%d frames: %zu keyframes with the weak interval 0, %zu with %.2f s (gaps %.3f-%.3f s)\n", frames,
              every.size(), spaced.size(), kWeakInterval, shortest_s, longest_s);
  EXPECT_GE(shortest_s, kWeakInterval - 1e-6);
  EXPECT_LE(longest_s, kWeakInterval + 0.5 * frame_s);  // the first frame past the interval
}

TEST_F(TrackerOnSimulatedSequence, ImuPredictsFromTheKeyFrameAfterLocalMappingUpdatedIt) {
  // Local BA in the callback moves the newest keyframes: the next IMU prediction starts from the
  // last keyframe's updated state with the preintegration since it (ORB-SLAM3's map-updated case).
  io::SequenceReader reader = io::SequenceReader::open(dir_->string());
  const FrameBuilder builder(orbOptions(), reader.calib());
  map::Atlas atlas(1);
  Tracker tracker(atlas, TrackerOptions(), builder.extractor().levelSigma2());
  tracker.setLocalMappingCallback(
      [](map::Map& map, const std::shared_ptr<map::KeyFrame>& kf) { localBundleAdjustNewest(map, kf, 5); });
  io::Trajectory estimate;
  int frames = 0, ok = 0, from_keyframe = 0;
  while (auto input = reader.next()) {
    if (frames == 10) tracker.setImuInitialised(imu::ImuBias(), imu::gravityWorld());
    if (frames == 60) tracker.setImuInitialised(imu::ImuBias(), imu::gravityWorld());  // a refinement: same values
    map::Frame frame = builder.build(*input, tracker.bias());
    if (frames == 0) frame.setPose_T_w_c(reader.groundTruth().front().T_w_x);
    const TrackingState state = tracker.track(frame);
    ++frames;
    if (tracker.stats().imu_from_keyframe) ++from_keyframe;
    if (state != TrackingState::kOk) continue;
    ++ok;
    estimate.push_back({frame.t_s(), tracker.T_w_c()});
  }
  const eval::AteResult ate =
      eval::computeAte(eval::associateTrajectories(reader.groundTruth(), estimate), false);
  std::printf("IMU + local BA: %d predictions from an updated keyframe, %d keyframes, ok %d of %d, ATE rmse %.4f m\n",
              from_keyframe, tracker.numKeyFrames(), ok, frames, ate.error_m.rmse);
  EXPECT_EQ(ok, frames);
  EXPECT_GE(from_keyframe, 1);
  EXPECT_LE(from_keyframe, tracker.numKeyFrames());
  EXPECT_LT(ate.error_m.rmse, 0.05);
}

TEST_F(TrackerOnSimulatedSequence, BlackFramesMakeTheTrackerLostWithoutCrashing) {
  io::SequenceReader reader = io::SequenceReader::open(dir_->string());
  const FrameBuilder builder(orbOptions(), reader.calib());
  map::Atlas atlas(1);
  Tracker tracker(atlas, TrackerOptions(), builder.extractor().levelSigma2());
  std::vector<TrackingState> states;
  for (int k = 0; k < 20; ++k) {
    auto input = reader.next();
    ASSERT_TRUE(input.has_value());
    if (k >= 10 && k < 15) input->color_bgr.setTo(cv::Scalar::all(0));
    map::Frame frame = builder.build(*input);
    states.push_back(tracker.track(frame));
  }
  for (int k = 0; k < 10; ++k) EXPECT_EQ(states[k], TrackingState::kOk) << "frame " << k;
  for (int k = 10; k < 15; ++k) EXPECT_EQ(states[k], TrackingState::kLost) << "frame " << k;
  std::printf("after the black frames:");
  for (int k = 15; k < 20; ++k) std::printf(" %s", trackingStateName(states[k]));
  std::printf("\n");
  // Measured: re-tracked on the first real frame after 5 black ones (~6 cm of motion), from the
  // last good pose with doubled search windows.
  EXPECT_EQ(states[19], TrackingState::kOk);
}

TEST_F(TrackerOnSimulatedSequence, FramesWithoutDepthTrackOnTwoDimensionalMatches) {
  io::SequenceReader reader = io::SequenceReader::open(dir_->string());
  const FrameBuilder builder(orbOptions(), reader.calib());
  map::Atlas atlas(1);
  Tracker tracker(atlas, TrackerOptions(), builder.extractor().levelSigma2());
  std::vector<TrackingState> states;
  int keyframes_at_gap = 0;
  for (int k = 0; k < 25; ++k) {
    auto input = reader.next();
    ASSERT_TRUE(input.has_value());
    if (k == 10) keyframes_at_gap = tracker.numKeyFrames();
    if (k >= 10 && k < 20) input->depth_m.setTo(cv::Scalar::all(0));
    map::Frame frame = builder.build(*input);
    states.push_back(tracker.track(frame));
  }
  // Existing map points still constrain the pose through 2-D edges; no keyframe inserts points
  // without depth (a keyframe may be created, with no new points).
  std::printf("without depth:");
  for (int k = 10; k < 25; ++k) std::printf(" %s", trackingStateName(states[static_cast<std::size_t>(k)]));
  std::printf(" (%d keyframes before, %d after)\n", keyframes_at_gap, tracker.numKeyFrames());
  // Measured: every frame of the 10-frame (0.33 s) gap stays tracked.
  for (int k = 0; k < 25; ++k) EXPECT_EQ(states[static_cast<std::size_t>(k)], TrackingState::kOk) << "frame " << k;
}

TEST(Tracker, BlackFirstFrameDoesNotInitialise) {
  SensorCalib calib;
  calib.camera.camera = PinholeCamera(262.5, 262.5, 159.5, 119.5, 320, 240);
  const FrameBuilder builder(OrbOptions(), calib);
  io::RgbdImuFrame input;
  input.color_bgr = cv::Mat(240, 320, CV_8UC3, cv::Scalar::all(0));
  input.depth_m = cv::Mat(240, 320, CV_32F, cv::Scalar(1.0f));
  map::Frame frame = builder.build(input);
  EXPECT_EQ(frame.numKeypoints(), 0);
  map::Atlas atlas(1);
  map::Map& map = atlas.activeMap();
  Tracker tracker(atlas, TrackerOptions(), builder.extractor().levelSigma2());
  EXPECT_EQ(tracker.track(frame), TrackingState::kNotInitialised);
  EXPECT_EQ(map.numKeyFrames(), 0u);
}

}  // namespace
}  // namespace ltlo::tracking
