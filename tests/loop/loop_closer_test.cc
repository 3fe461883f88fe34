// LoopCloser on synthetic maps (the lap of loop_scene.h). After one lap the camera revisits the
// start: the closer must close exactly one loop there, not without a revisit, merge two maps of the
// same place, and give the same result from its own thread (fixed seeds, no images).
#include "ltlo/loop/loop_closer.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <unordered_map>

#include "bow/vocabulary.h"
#include "loop_scene.h"
#include "ltlo/place/guided_place_match.h"

namespace ltlo::loop {
namespace {

using place::GuidedPlaceMatch;
using place::GuidedPlaceMatchOptions;
using place::guidedPlaceMatch;
using place::translationWithHeldRotation;
// The lap (loop_scene.h).
using test::driftStep;
using test::kCamera;
using test::kStepsPerLap;
using test::SceneBuilder;
using test::truePose_T_w_b;
using test::world;

LoopCloserOptions closerOptions() {
  LoopCloserOptions options;
  options.loop.full_ba_iterations = 10;
  options.loop.refine_keyframes = 0;  // one full BA per correction (RefinesTheLoopWith... turns it on)
  return options;
}

/// Mean translation error of the revisiting keyframes against the keyframes of the first lap at the
/// same true place (the loop seam; zero when the map is consistent).
double seamError_m(const SceneBuilder& scene) {
  const auto& kfs = scene.keyFrames();
  double sum = 0.0;
  int n = 0;
  for (std::size_t k = kStepsPerLap; k < kfs.size(); ++k) {
    const SE3 relative = kfs[k - kStepsPerLap]->T_w_b().inverse() * kfs[k]->T_w_b();
    sum += relative.translation().norm();
    ++n;
  }
  return sum / n;
}

constexpr int kLoopSteps = kStepsPerLap + 8;

/// What a synchronous run of `steps` keyframes of the drifting lap scene left: the seam, the full BAs
/// run, the loops closed and mapping's pauses and resumes.
struct LapsOutcome {
  double seam_m = 0.0;
  std::size_t full_bas = 0;
  int loops = 0;
  int pauses = 0, resumes = 0;
};

LapsOutcome runLaps(const LoopCloserOptions& options, int steps) {
  map::Atlas atlas(world().vocabulary->numWords());
  LapsOutcome outcome;
  TimingStats timing;
  LoopCloser closer(atlas, options, MappingControl{[&] { ++outcome.pauses; }, [&] { ++outcome.resumes; }}, &timing);
  SceneBuilder scene(atlas, driftStep());
  for (int step = 0; step < steps; ++step) closer.processKeyFrame(scene.add(step));
  outcome.seam_m = seamError_m(scene);
  outcome.full_bas = timing.stage("loop.global_ba").count;
  outcome.loops = closer.numLoops();
  return outcome;
}


TEST(LoopCloser, ClosesTheLoopOnceWhenTheStartIsRevisited) {
  double seam_without = 0.0;
  {
    map::Atlas atlas(world().vocabulary->numWords());
    LoopCloserOptions options = closerOptions();
    options.loop.enabled = false;
    LoopCloser closer(atlas, options, MappingControl{});
    SceneBuilder scene(atlas, driftStep());
    for (int step = 0; step < kLoopSteps; ++step) closer.processKeyFrame(scene.add(step));
    EXPECT_EQ(closer.numLoops(), 0);
    seam_without = seamError_m(scene);
  }
  map::Atlas atlas(world().vocabulary->numWords());
  int pauses = 0, resumes = 0;
  TimingStats timing;
  LoopCloser closer(atlas, closerOptions(), MappingControl{[&] { ++pauses; }, [&] { ++resumes; }}, &timing);
  SceneBuilder scene(atlas, driftStep());
  std::uint64_t version_before = 0;
  for (int step = 0; step < kLoopSteps; ++step) {
    version_before = atlas.activeMap().version();
    closer.processKeyFrame(scene.add(step));
    if (closer.numLoops() == 1 && closer.events().back().current == scene.keyFrames().back()->id()) {
      EXPECT_GT(atlas.activeMap().version(), version_before);  // tracking sees the correction
    }
  }
  const double seam_with = seamError_m(scene);
  ASSERT_EQ(closer.numLoops(), 1);
  EXPECT_EQ(closer.numMerges(), 0);
  const std::vector<LoopEvent> events = closer.events();
  ASSERT_EQ(events.size(), 1u);
  const LoopEvent& loop = events[0];
  // The loop keyframe is of the first lap at (about) the same place as the current one.
  int current_step = -1, loop_step = -1;
  for (std::size_t k = 0; k < scene.keyFrames().size(); ++k) {
    if (scene.keyFrames()[k]->id() == loop.current) current_step = scene.steps()[k];
    if (scene.keyFrames()[k]->id() == loop.loop) loop_step = scene.steps()[k];
  }
  std::printf(
      "[ CLOSER   ] loop kf step %d ~ step %d, %d inliers, correction %.3f m; seam error %.4f m without loop "
      "closing -> %.4f m with; mapping paused %d times\n",
      current_step, loop_step, loop.inliers, loop.correction_m, seam_without, seam_with, pauses);
  EXPECT_GE(current_step, kStepsPerLap - 1);
  EXPECT_LE(std::abs((current_step % kStepsPerLap) - loop_step), 2);
  EXPECT_GE(loop.inliers, 20);
  EXPECT_GT(loop.correction_m, 0.1);
  EXPECT_FALSE(loop.merge);
  EXPECT_GT(seam_without, 0.2);
  EXPECT_LT(seam_with, seam_without / 5.0);
  EXPECT_EQ(pauses, resumes);
  EXPECT_EQ(pauses, 2);  // correction, then the full BA's write-back
  EXPECT_FALSE(closer.globalBaRunning());
  EXPECT_EQ(timing.stage("loop.keyframe").count, static_cast<std::size_t>(kLoopSteps));
  EXPECT_EQ(timing.stage("loop.correction").count, 1u);
  EXPECT_EQ(timing.stage("loop.global_ba").count, 1u);
  std::printf("[ CLOSER   ] keyframe median %.2f ms (max %.1f ms with the synchronous full BA), correction %.1f ms, "
              "full BA %.1f ms\n",
              1e3 * timing.stage("loop.keyframe").median_s, 1e3 * timing.stage("loop.keyframe").max_s,
              1e3 * timing.stage("loop.correction").max_s, 1e3 * timing.stage("loop.global_ba").max_s);
  EXPECT_EQ(atlas.keyFrameDatabase().size(), static_cast<std::size_t>(kLoopSteps));
}

// Loop.Proximity: with gravity known, a keyframe whose loop BoW cannot confirm (here the BoW path
// needs 20 consistent queries, more than the revisit has) searches its map's old keyframes near its
// own pose (guided search: offset vote, narrow windows, pose refinement, gated by
// Loop.ProximitySigma). The drift leaves a seam the search reaches (1.1 degrees of yaw per lap);
// the loop is closed by proximity, the loop pair then agrees with the truth within 1 cm and the
// seam shrinks. With the switch off, or without gravity
// (RGB-D only), no loop is closed.
TEST(LoopCloser, WithGravityALoopIsClosedByProximityWhenBowCannot) {
  // Mostly translation: with the IMU the gyro keeps the yaw drift near a degree per lap.
  const SE3 drift = SE3::exp((Vec6() << 0.0005, 0.0008, 0.0005, 0.008, 0.002, 0.006).finished());
  double loop_pair_error_m = -1.0;
  auto runWith = [&](bool proximity, bool with_gravity, double* seam_m) {
    map::Atlas atlas(world().vocabulary->numWords());
    LoopCloserOptions options = closerOptions();
    options.loop.min_consistency = 20;
    options.loop.proximity = proximity;
    options.rejoin_search.max_keyframes = 20;
    MappingControl control;
    if (with_gravity) control.gravity_w = [] { return std::optional<Vec3>(Vec3(0.0, 0.0, -9.81)); };
    LoopCloser closer(atlas, options, control);
    SceneBuilder scene(atlas, drift);
    for (int step = 0; step < kLoopSteps; ++step) closer.processKeyFrame(scene.add(step));
    *seam_m = seamError_m(scene);
    const std::vector<LoopEvent> events = closer.events();
    if (!events.empty()) {
      // The loop pair against the truth: estimated vs true relative pose.
      int current = -1, loop = -1;
      for (std::size_t k = 0; k < scene.keyFrames().size(); ++k) {
        if (scene.keyFrames()[k]->id() == events.front().current) current = static_cast<int>(k);
        if (scene.keyFrames()[k]->id() == events.front().loop) loop = static_cast<int>(k);
      }
      if (current >= 0 && loop >= 0) {
        const SE3 estimated = scene.keyFrames()[loop]->T_w_b().inverse() * scene.keyFrames()[current]->T_w_b();
        const SE3 truth = truePose_T_w_b(scene.steps()[loop]).inverse() * truePose_T_w_b(scene.steps()[current]);
        loop_pair_error_m = (estimated.translation() - truth.translation()).norm();
      }
    }
    return events;
  };
  double seam_off = 0.0, seam_without_gravity = 0.0, seam_on = 0.0;
  const std::vector<LoopEvent> off = runWith(false, true, &seam_off);
  const std::vector<LoopEvent> without_gravity = runWith(true, false, &seam_without_gravity);
  const std::vector<LoopEvent> on = runWith(true, true, &seam_on);
  std::printf("[ CLOSER   ] proximity: seam %.4f m without it -> %.4f m with %zu loop(s)%s; loop pair error %.4f m\n",
              seam_off, seam_on, on.size(), on.empty() ? "" : (on.front().proximity ? " (proximity)" : " (BoW)"),
              loop_pair_error_m);
  EXPECT_TRUE(off.empty());
  EXPECT_TRUE(without_gravity.empty());
  EXPECT_GT(seam_off, 0.05);  // the premise: a seam to close, within the search's 3 sigma (0.3 m)
  EXPECT_LT(seam_off, 0.3);
  ASSERT_GE(on.size(), 1u);
  EXPECT_TRUE(on.front().proximity);
  EXPECT_FALSE(on.front().merge);
  EXPECT_GE(on.front().inliers, 20);
  // The loop pair agrees with the truth; the keyframes after the loop drift on (the seam is their
  // mean), so the seam shrinks less than that.
  EXPECT_GE(loop_pair_error_m, 0.0);
  EXPECT_LT(loop_pair_error_m, 0.01);
  EXPECT_LT(seam_on, 0.75 * seam_off);
}

// Loop.MaxCorrectionShare: with gravity known, a BoW loop may correct the current keyframe by at
// most 3 Loop.ProximitySigma plus the share of the path travelled since the loop keyframe. The
// lap's drift (driftStep) needs a correction of 0.1 m or more after one lap: closed with no limit
// and with a share of the whole path, rejected when the limit is made smaller than the correction
// (a place that only looks the same would need metres); without gravity there is no limit.
TEST(LoopCloser, WithGravityALoopCorrectingMoreThanTheDriftAllowsIsRejected) {
  auto runWith = [&](double share, double sigma_m, bool with_gravity) {
    map::Atlas atlas(world().vocabulary->numWords());
    LoopCloserOptions options = closerOptions();
    options.loop.proximity = false;
    options.loop.max_correction_share = share;
    options.loop.proximity_sigma_m = sigma_m;
    MappingControl control;
    if (with_gravity) control.gravity_w = [] { return std::optional<Vec3>(Vec3(0.0, 0.0, -9.81)); };
    LoopCloser closer(atlas, options, control);
    SceneBuilder scene(atlas, driftStep());
    for (int step = 0; step < kLoopSteps; ++step) closer.processKeyFrame(scene.add(step));
    return closer.events();
  };
  const std::vector<LoopEvent> unlimited = runWith(0.0, 0.10, true);
  ASSERT_EQ(unlimited.size(), 1u);
  const double correction_m = unlimited.front().correction_m;
  EXPECT_GT(correction_m, 0.1);
  EXPECT_EQ(runWith(1.0, 0.10, true).size(), 1u);  // a lap is longer than its drift
  EXPECT_TRUE(runWith(1e-4, 0.005, true).empty());  // limit 0.015 m plus 0.1 mm per metre
  EXPECT_EQ(runWith(1e-4, 0.005, false).size(), 1u);
  std::printf("[ CLOSER   ] loop correction %.3f m: closed without a limit, rejected under a limit of 0.015 m\n",
              correction_m);
}

// Loop.WaitForImu: with an IMU, a map closes no BoW loop until the IMU is initialised (gravity
// known), so every correction can be checked against the drift; it closes the same loop once it is.
// Without the switch the loop closes before the initialisation too.
TEST(LoopCloser, WithAnImuNoLoopIsClosedBeforeTheImuIsInitialised) {
  auto runWith = [&](bool wait_for_imu, int initialised_at_step) {
    map::Atlas atlas(world().vocabulary->numWords());
    LoopCloserOptions options = closerOptions();
    options.loop.proximity = false;
    options.loop.wait_for_imu = wait_for_imu;
    int step = 0;
    MappingControl control;
    control.gravity_w = [&step, initialised_at_step] {
      return step >= initialised_at_step ? std::optional<Vec3>(Vec3(0.0, 0.0, -9.81)) : std::nullopt;
    };
    LoopCloser closer(atlas, options, control);
    SceneBuilder scene(atlas, driftStep());
    for (step = 0; step < kLoopSteps; ++step) closer.processKeyFrame(scene.add(step));
    return closer.events();
  };
  const std::vector<LoopEvent> closed = runWith(false, kLoopSteps);
  ASSERT_EQ(closed.size(), 1u);
  EXPECT_TRUE(runWith(true, kLoopSteps).empty());  // the IMU never initialised
  const std::vector<LoopEvent> after_initialisation = runWith(true, 0);
  ASSERT_EQ(after_initialisation.size(), 1u);
  EXPECT_EQ(after_initialisation.front().current, closed.front().current);
  EXPECT_EQ(after_initialisation.front().loop, closed.front().loop);
}

// The yaw a guided place match fixes (GuidedPlaceMatch::yaw_sigma_rad, which gates the rejoin and
// the proximity loop): a keyframe seeing the whole view of a mapped place pins its yaw; the same
// place seen through a strip of the image (the rest covered) holds as many matches in a narrow
// fan, where a turn about the vertical trades for a sideways step, and its yaw sigma is about three
// times wider (with 32 matches, more than a rejoin needs).
TEST(LoopCloser, AStripOfTheViewFixesTheYawWorseThanTheWholeView) {
  map::Atlas atlas(world().vocabulary->numWords());
  SceneBuilder lap(atlas, SE3());
  for (int step = 0; step < kStepsPerLap; ++step) lap.add(step);
  map::Map& mapped = *atlas.map(lap.keyFrames().front()->mapId());
  auto placeMatch = [&](std::optional<std::pair<double, double>> columns) {
    map::Atlas other(world().vocabulary->numWords());
    SceneBuilder view(other, SE3());
    if (columns) view.restrictView(columns->first, columns->second);
    const std::shared_ptr<map::KeyFrame> kf = view.add(kStepsPerLap / 2);
    GuidedPlaceMatchOptions options;
    options.sigma_position_m = 0.05;
    options.refine_pose = true;
    options.bf_px_m = kCamera.fx() * 0.08;
    return guidedPlaceMatch(*kf, mapped, kf->T_w_c(), options);
  };
  const GuidedPlaceMatch whole = placeMatch(std::nullopt);
  const GuidedPlaceMatch strip = placeMatch(std::make_pair(250.0, 390.0));
  std::printf("[ CLOSER   ] yaw sigma: whole view %.3f deg (%zu matches), strip %.3f deg (%zu matches)\n",
              whole.yaw_sigma_rad * 180.0 / M_PI, whole.matches.size(), strip.yaw_sigma_rad * 180.0 / M_PI,
              strip.matches.size());
  ASSERT_TRUE(whole.success);
  ASSERT_TRUE(strip.success);
  EXPECT_GE(strip.matches.size(), 20u);  // enough matches for a rejoin: only their spread differs
  EXPECT_TRUE(std::isfinite(whole.yaw_sigma_rad));
  EXPECT_GT(strip.yaw_sigma_rad, 2.5 * whole.yaw_sigma_rad);  // measured 0.108 vs 0.037 deg
}

// A rejoin whose matches crowd into a strip (their yaw wide) keeps the dead reckoning's rotation
// and takes the translation from the matches: the strip's matches put a camera predicted 14 cm
// off, with the rotation right or 0.1 deg off in yaw (gyro drift), back within a centimetre.
TEST(LoopCloser, AStripOfTheViewFixesTheTranslationUnderAHeldRotation) {
  map::Atlas atlas(world().vocabulary->numWords());
  SceneBuilder lap(atlas, SE3());
  for (int step = 0; step < kStepsPerLap; ++step) lap.add(step);
  map::Map& mapped = *atlas.map(lap.keyFrames().front()->mapId());
  map::Atlas other(world().vocabulary->numWords());
  SceneBuilder view(other, SE3());
  view.restrictView(250.0, 390.0);
  const std::shared_ptr<map::KeyFrame> kf = view.add(kStepsPerLap / 2);
  const SE3 T_w_c_true = kf->T_w_c();
  GuidedPlaceMatchOptions options;
  options.sigma_position_m = 0.1;
  options.refine_pose = true;
  options.bf_px_m = kCamera.fx() * 0.08;
  for (const double yaw_error_deg : {0.0, 0.1}) {
    const SE3 T_w_c_pred(so3ExpQuat(Vec3(0.0, 0.0, yaw_error_deg * M_PI / 180.0)) * T_w_c_true.quaternion(),
                         T_w_c_true.translation() + Vec3(0.12, -0.07, 0.02));
    const GuidedPlaceMatch found = guidedPlaceMatch(*kf, mapped, T_w_c_pred, options);
    ASSERT_TRUE(found.success) << yaw_error_deg;
    const GuidedPlaceMatch held = translationWithHeldRotation(*kf, mapped, found, T_w_c_pred, 20);
    const double error_m = (held.T_w_c.translation() - T_w_c_true.translation()).norm();
    std::printf("[ CLOSER   ] held rotation (%.1f deg off): %zu of %zu matches, translation %.4f m off (free pose %.4f m)\n",
                yaw_error_deg, held.matches.size(), found.matches.size(), error_m,
                (found.T_w_c.translation() - T_w_c_true.translation()).norm());
    ASSERT_TRUE(held.success) << yaw_error_deg;
    EXPECT_GE(held.matches.size(), 20u);
    EXPECT_LT(error_m, 0.01) << yaw_error_deg;
    EXPECT_NEAR(held.distance_m, (held.T_w_c.translation() - T_w_c_pred.translation()).norm(), 1e-12);
    EXPECT_LT(so3Log(held.T_w_c.quaternion().conjugate() * T_w_c_pred.quaternion()).norm(), 1e-12);
  }
  // Too few matches for the caller's minimum: no pose.
  const GuidedPlaceMatch found = guidedPlaceMatch(*kf, mapped, T_w_c_true, options);
  EXPECT_FALSE(translationWithHeldRotation(*kf, mapped, found, T_w_c_true, 1000).success);
}

TEST(LoopCloser, NoLoopWithoutARevisit) {
  map::Atlas atlas(world().vocabulary->numWords());
  LoopCloser closer(atlas, closerOptions(), MappingControl{});
  SceneBuilder scene(atlas, driftStep());
  // Most of a lap: the last keyframe's view does not overlap the first one's.
  for (int step = 0; step < kStepsPerLap - 3; ++step) closer.processKeyFrame(scene.add(step));
  EXPECT_EQ(closer.numLoops(), 0);
  EXPECT_EQ(closer.numMerges(), 0);
  EXPECT_TRUE(closer.events().empty());
}

/// Loops closed on the revisit lap when the keyframes of steps in [dynamic_begin, dynamic_end) are
/// all dynamic (gamma 0: static area 0 < Loop.MinStaticRatio, as when a box covers the view).
int loopsWithDynamicSteps(int dynamic_begin, int dynamic_end) {
  map::Atlas atlas(world().vocabulary->numWords());
  LoopCloser closer(atlas, closerOptions(), MappingControl{});
  SceneBuilder scene(atlas, driftStep());
  for (int step = 0; step < kLoopSteps; ++step) {
    const std::shared_ptr<map::KeyFrame> kf = scene.add(step);
    if (step >= dynamic_begin && step < dynamic_end) {
      kf->setGamma({0.0});
      EXPECT_LT(kf->staticAreaRatio(), closerOptions().loop.min_static_ratio);
    }
    closer.processKeyFrame(kf);
  }
  return closer.numLoops() + closer.numMerges();
}

TEST(LoopCloser, KeyFramesBelowTheStaticAreaRatioTakeNoPartInPlaceRecognition) {
  EXPECT_EQ(loopsWithDynamicSteps(0, 0), 1);  // the reference: the revisit closes the loop
  // The revisiting keyframes are dynamic: they do not query.
  EXPECT_EQ(loopsWithDynamicSteps(kStepsPerLap, kLoopSteps), 0);
  // The first lap's keyframes around the start are dynamic: they are no candidates.
  EXPECT_EQ(loopsWithDynamicSteps(0, kLoopSteps - kStepsPerLap + 4), 0);
}

TEST(LoopCloser, SkipsBadKeyFramesAndKeyFramesWithoutBow) {
  map::Atlas atlas(world().vocabulary->numWords());
  LoopCloser closer(atlas, closerOptions(), MappingControl{});
  SceneBuilder scene(atlas, SE3());
  closer.processKeyFrame(scene.add(0));
  closer.processKeyFrame(scene.add(1));
  EXPECT_EQ(atlas.keyFrameDatabase().size(), 2u);
  // Without BoW (never given to the database), culled (bad), or none at all.
  map::Frame frame(9.0, kCamera, SE3(), features::OrbFeatures{}, {}, {1.0f});
  frame.setPose_T_w_b(SE3());
  closer.processKeyFrame(atlas.activeMap().createKeyFrame(frame));
  const std::shared_ptr<map::KeyFrame> culled = scene.add(2);
  ASSERT_TRUE(atlas.activeMap().eraseKeyFrame(culled->id()));
  closer.processKeyFrame(culled);
  closer.processKeyFrame(nullptr);
  EXPECT_EQ(atlas.keyFrameDatabase().size(), 2u);
  EXPECT_TRUE(closer.events().empty());
}

/// An old map of the first half lap, then tracking is lost and a new map sees part of it again; returns
/// the index of the new map's keyframe at which the maps were merged (-1: none).
int mergeAfterTrackingLoss(int min_inliers) {
  map::Atlas atlas(world().vocabulary->numWords());
  int pauses = 0, resumes = 0;
  LoopCloserOptions options = closerOptions();
  options.loop.min_inliers = min_inliers;
  LoopCloser closer(atlas, options, MappingControl{[&] { ++pauses; }, [&] { ++resumes; }});
  SceneBuilder old_scene(atlas, SE3());
  for (int step = 0; step < 12; ++step) closer.processKeyFrame(old_scene.add(step));
  const map::MapId old_map = atlas.activeMapId();
  // Tracking lost: a new map whose world frame is the first new keyframe's (an arbitrary offset).
  atlas.createNewMap();
  const map::MapId new_map = atlas.activeMapId();
  EXPECT_EQ(atlas.numMaps(), 2u);
  SceneBuilder new_scene(atlas, SE3());
  const SE3 T_new_w = SE3(so3Exp(Vec3(0.3, -0.2, 1.0)), Vec3(1.0, -2.0, 0.5));
  for (int step = 4; step < 10; ++step) closer.processKeyFrame(new_scene.add(step, T_new_w * truePose_T_w_b(4)));
  EXPECT_EQ(closer.numMerges(), 1);
  if (closer.numMerges() != 1) return -1;
  EXPECT_EQ(closer.numLoops(), 0);
  EXPECT_EQ(atlas.numMaps(), 1u);
  EXPECT_EQ(atlas.activeMapId(), old_map);  // the merged-away map was the active one
  const LoopEvent event = closer.events().at(0);
  EXPECT_TRUE(event.merge);
  EXPECT_EQ(event.map, old_map);
  // Every keyframe of the new map is now in the old map's frame (= the true one) at its true pose.
  double max_error_m = 0.0;
  for (std::size_t k = 0; k < new_scene.keyFrames().size(); ++k) {
    const map::KeyFrame& kf = *new_scene.keyFrames()[k];
    EXPECT_EQ(kf.mapId(), old_map);
    EXPECT_NE(kf.mapId(), new_map);
    const double error_m = (kf.T_w_b().translation() - truePose_T_w_b(new_scene.steps()[k]).translation()).norm();
    max_error_m = std::max(max_error_m, error_m);
  }
  int merged_at = -1;
  for (std::size_t k = 0; k < new_scene.keyFrames().size(); ++k) {
    if (new_scene.keyFrames()[k]->id() == event.current) merged_at = static_cast<int>(k);
  }
  std::printf(
      "[ MERGE    ] Loop.MinInliers %d: merged at new keyframe %d of %zu, %d inliers, max position error after "
      "%.2e m\n",
      min_inliers, merged_at, new_scene.keyFrames().size(), event.inliers, max_error_m);
  EXPECT_LT(max_error_m, 1e-3);
  EXPECT_EQ(pauses, resumes);
  EXPECT_EQ(pauses, 2);  // merge, then the full BA's write-back
  return merged_at;
}

TEST(LoopCloser, MergesAMapStartedAfterTrackingLossAtOnceOnAStrongMatch) {
  // ~155 inliers >= 2 * 20: accepted before the consistency check completes.
  EXPECT_EQ(mergeAfterTrackingLoss(20), 0);
}

TEST(LoopCloser, MergesAfterThreeConsistentQueriesOnAnOrdinaryMatch) {
  // 2 * 100 inliers are not there: the place must be recognised by three consecutive keyframes.
  EXPECT_EQ(mergeAfterTrackingLoss(100), 2);
}

/// Builds the whole loop sequence first (no correction during the build), then feeds it.
struct PrebuiltLoop {
  explicit PrebuiltLoop(int num_steps = kLoopSteps) : atlas(world().vocabulary->numWords()), scene(atlas, driftStep()) {
    for (int step = 0; step < num_steps; ++step) scene.add(step);
  }
  map::Atlas atlas;
  SceneBuilder scene;
};

TEST(LoopCloser, ThreadedRunMatchesTheSynchronousOne) {
  PrebuiltLoop sync_run;
  LoopCloser sync_closer(sync_run.atlas, closerOptions(), MappingControl{});
  for (const auto& kf : sync_run.scene.keyFrames()) sync_closer.processKeyFrame(kf);
  ASSERT_EQ(sync_closer.numLoops(), 1);

  PrebuiltLoop threaded_run;
  std::atomic<int> pauses{0}, resumes{0};
  TimingStats timing;
  LoopCloser closer(threaded_run.atlas, closerOptions(), MappingControl{[&] { ++pauses; }, [&] { ++resumes; }},
                    &timing);
  std::thread loop_thread([&] { closer.run(); });
  // A tracking-like reader of poses, points and the map version meanwhile (a fixed amount of work).
  std::thread reader([&] {
    map::Map& map = threaded_run.atlas.activeMap();
    double sum = 0.0;
    for (int pass = 0; pass < 200; ++pass) {
      sum += static_cast<double>(map.version());
      for (const auto& kf : map.keyFrames()) sum += kf->T_w_b().translation().x();
      for (const auto& point : map.mapPoints()) sum += point->p_w().z();
    }
    EXPECT_TRUE(std::isfinite(sum));
  });
  for (const auto& kf : threaded_run.scene.keyFrames()) closer.insertKeyFrame(kf);
  closer.requestFinish();
  loop_thread.join();
  reader.join();
  closer.waitForGlobalBa();
  EXPECT_FALSE(closer.globalBaRunning());
  EXPECT_EQ(pauses.load(), resumes.load());
  EXPECT_EQ(pauses.load(), 2);
  ASSERT_EQ(closer.numLoops(), 1);
  const LoopEvent a = sync_closer.events()[0], b = closer.events()[0];
  EXPECT_EQ(a.current, b.current);
  EXPECT_EQ(a.loop, b.loop);
  EXPECT_EQ(a.inliers, b.inliers);
  double max_difference_m = 0.0;
  for (std::size_t k = 0; k < sync_run.scene.keyFrames().size(); ++k) {
    max_difference_m = std::max(max_difference_m, (sync_run.scene.keyFrames()[k]->T_w_b().translation() -
                                                   threaded_run.scene.keyFrames()[k]->T_w_b().translation())
                                                      .norm());
  }
  std::printf("[ THREADED ] loop %s ~ %s, max keyframe difference to the synchronous run %.2e m\n",
              std::to_string(b.current.value).c_str(), std::to_string(b.loop.value).c_str(), max_difference_m);
  EXPECT_LT(max_difference_m, 1e-6);
  EXPECT_EQ(timing.stage("loop.keyframe").count, static_cast<std::size_t>(kLoopSteps));
  EXPECT_EQ(timing.stage("loop.correction").count, 1u);
  EXPECT_EQ(timing.stage("loop.global_ba").count, 1u);
}

// Loop.RefineKeyFrames: the full BA after the loop knows only the closing keyframe's matches; the
// keyframes that follow keep tracking the old side's points, and the drift they accumulate meanwhile
// is left in the map unless the full BA runs again with what they saw.
TEST(LoopCloser, RefinesTheLoopWithTheKeyFramesThatFollowIt) {
  constexpr int kSteps = kStepsPerLap + 14;
  auto runWith = [](int refine_keyframes) {
    LoopCloserOptions options = closerOptions();
    options.loop.refine_keyframes = refine_keyframes;
    return runLaps(options, kSteps);
  };
  const LapsOutcome once = runWith(0);
  const LapsOutcome refined = runWith(10);
  std::printf("[ REFINE   ] seam error %.4f m with one full BA per loop -> %.4f m with the refining one "
              "10 keyframes later (%zu -> %zu full BA runs, %d / %d loops)\n",
              once.seam_m, refined.seam_m, once.full_bas, refined.full_bas, once.loops, refined.loops);
  ASSERT_EQ(once.loops, 1);
  ASSERT_EQ(refined.loops, 1);
  EXPECT_EQ(once.full_bas, 1u);
  EXPECT_EQ(refined.full_bas, 2u);
  EXPECT_EQ(refined.pauses, refined.resumes);
  EXPECT_EQ(refined.pauses, 3);  // the correction and two write-backs
  EXPECT_LT(refined.seam_m, 0.25 * once.seam_m);
}

// Loop.FullBaBudget: the full BAs, each counted as the keyframes of its map, at most `budget` per
// keyframe received. Two laps close three loops; with no limit each runs its full BA. With a budget
// of 1 only the first fits: the later corrections stand alone, and the seam they leave is larger
// than with a full BA on every loop (this scene drifts 1.1 deg of yaw a lap, far beyond a real run)
// but a small part of the seam without loop closing. With 1.5 the second loop's full BA waits for
// the budget and runs 5 keyframes later, with their observations, and the seam closes as well.
TEST(LoopCloser, FullBasStayWithinTheirBudget) {
  constexpr int kSteps = 2 * kStepsPerLap + 4;
  auto runWith = [](double budget, bool loops = true) {
    LoopCloserOptions options = closerOptions();
    options.loop.full_ba_budget = budget;
    options.loop.enabled = loops;
    return runLaps(options, kSteps);
  };
  const LapsOutcome unlimited = runWith(0.0);
  const LapsOutcome tight = runWith(1.0);
  const LapsOutcome waiting = runWith(1.5);
  const LapsOutcome without = runWith(0.0, false);
  std::printf("[ BUDGET   ] no limit: %d loops, %zu full BAs, seam %.4f m; budget 1: %d loops, %zu full BA, seam %.4f m; "
              "budget 1.5: %zu full BAs, seam %.4f m; without loop closing: seam %.4f m\n",
              unlimited.loops, unlimited.full_bas, unlimited.seam_m, tight.loops, tight.full_bas, tight.seam_m,
              waiting.full_bas, waiting.seam_m, without.seam_m);
  ASSERT_GE(unlimited.loops, 2);
  EXPECT_EQ(unlimited.full_bas, static_cast<std::size_t>(unlimited.loops));
  EXPECT_EQ(tight.loops, unlimited.loops);
  EXPECT_EQ(tight.full_bas, 1u);
  EXPECT_EQ(without.loops, 0);
  EXPECT_LT(unlimited.seam_m, 0.005);
  EXPECT_LT(tight.seam_m, 0.25 * without.seam_m);
  EXPECT_EQ(waiting.loops, unlimited.loops);
  EXPECT_EQ(waiting.full_bas, 2u);
  EXPECT_LT(waiting.seam_m, 0.005);
}

TEST(LoopCloser, ALaterLoopAbortsOrFollowsTheRunningFullBa) {
  // Two laps: the second revisit closes another loop while the first full BA may still run (then it
  // is aborted and joined before the correction; either way pauses and resumes stay balanced).
  PrebuiltLoop run(2 * kStepsPerLap + 4);
  std::atomic<int> pauses{0}, resumes{0};
  TimingStats timing;
  LoopCloser closer(run.atlas, closerOptions(), MappingControl{[&] { ++pauses; }, [&] { ++resumes; }}, &timing);
  std::thread loop_thread([&] { closer.run(); });
  for (const auto& kf : run.scene.keyFrames()) closer.insertKeyFrame(kf);
  closer.requestFinish();
  loop_thread.join();
  EXPECT_FALSE(closer.globalBaRunning());
  std::printf("[ TWO LAPS ] %d loops, %zu full BA runs finished or aborted, mapping paused %d times\n",
              closer.numLoops(), timing.stage("loop.global_ba").count, pauses.load());
  EXPECT_GE(closer.numLoops(), 2);
  // Every loop joins keyframes at the same true place (no false loop).
  std::unordered_map<std::uint64_t, int> step_of;
  for (std::size_t k = 0; k < run.scene.keyFrames().size(); ++k) {
    step_of[run.scene.keyFrames()[k]->id().value] = run.scene.steps()[k];
  }
  for (const LoopEvent& event : closer.events()) {
    const int apart = std::abs(step_of.at(event.current.value) - step_of.at(event.loop.value)) % kStepsPerLap;
    EXPECT_LE(std::min(apart, kStepsPerLap - apart), 2) << event.current << " ~ " << event.loop;
  }
  EXPECT_EQ(pauses.load(), resumes.load());
  EXPECT_EQ(timing.stage("loop.global_ba").count, static_cast<std::size_t>(closer.numLoops()));
  EXPECT_GE(pauses.load(), closer.numLoops() + 1);  // each correction, and the last full BA's write-back
}

}  // namespace
}  // namespace ltlo::loop
