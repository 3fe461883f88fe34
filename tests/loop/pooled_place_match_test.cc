// Pooled place matching (pooled_place_match.h) on the lap of loop_scene.h: a map of one lap is the
// target; a second map sees the same place through a narrow strip of the image (the rest covered,
// as behind a box), placed in a world 0.15 m and 0.5 deg (yaw) off, as a map started after a long
// dead-reckoned stretch is. One keyframe of it matches too few points to be accepted; the window of
// four, pooled by their relative poses, recovers the true pose with a yaw it can fix.
#include "ltlo/place/pooled_place_match.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "loop_scene.h"
#include "ltlo/map/keyframe.h"

namespace ltlo::loop {
namespace {

using place::GuidedPlaceMatch;
using place::GuidedPlaceMatchOptions;
using place::guidedPlaceMatch;
using place::pooledPlaceMatch;
using place::poolingWindow;
using test::kStepsPerLap;
using test::SceneBuilder;
using test::truePose_T_w_b;
using test::world;

/// The strip's image columns: about a dozen of the wall's points per keyframe.
constexpr double kStripFirst_px = 295.0;
constexpr double kStripLast_px = 345.0;
constexpr int kFirstStep = 6;
constexpr int kWindow = 4;

/// The world error of the second map: yaw about the vertical and a translation.
SE3 worldError() {
  return SE3(so3ExpQuat(Vec3(0.0, 0.0, 0.5 * M_PI / 180.0)), Vec3(0.11, -0.09, 0.04));
}

GuidedPlaceMatchOptions searchOptions() {
  GuidedPlaceMatchOptions options;
  options.sigma_position_m = 0.1;
  options.sigma_rotation_rad = 0.01;
  options.seed = 7;
  return options;
}

struct Scene {
  map::Atlas target_atlas{world().vocabulary->numWords()};
  map::Atlas source_atlas{world().vocabulary->numWords()};
  map::Map* target = nullptr;
  /// kWindow keyframes of the strip map, newest first (the keyframe placed, then the earlier ones).
  std::vector<std::shared_ptr<map::KeyFrame>> window;
  std::vector<int> steps;

  Scene() {
    SceneBuilder lap(target_atlas, SE3());
    for (int step = 0; step < kStepsPerLap; ++step) lap.add(step);
    target = target_atlas.map(lap.keyFrames().front()->mapId());
    SceneBuilder strip(source_atlas, SE3());
    strip.restrictView(kStripFirst_px, kStripLast_px);
    for (int k = 0; k < kWindow; ++k) {
      const int step = kFirstStep + k;
      const auto kf = strip.add(step, worldError() * truePose_T_w_b(step));
      window.insert(window.begin(), kf);
      steps.insert(steps.begin(), step);
    }
  }
};

double rotationError_deg(const SE3& a, const SE3& b) {
  return so3Log(a.quaternion().conjugate() * b.quaternion()).norm() * 180.0 / M_PI;
}

TEST(PooledPlaceMatch, OneKeyFrameOfAStripIsTooLittleAndTheWindowFindsThePlace) {
  Scene scene;
  const SE3 T_w_c_true = truePose_T_w_b(scene.steps.front());
  const SE3 T_w_c_pred = scene.window.front()->T_w_c();
  ASSERT_GT((T_w_c_pred.translation() - T_w_c_true.translation()).norm(), 0.1);

  const GuidedPlaceMatch alone = pooledPlaceMatch({scene.window.front()}, *scene.target, T_w_c_pred, searchOptions());
  const GuidedPlaceMatch single = guidedPlaceMatch(*scene.window.front(), *scene.target, T_w_c_pred, searchOptions());
  const GuidedPlaceMatch pooled = pooledPlaceMatch(scene.window, *scene.target, T_w_c_pred, searchOptions());
  std::printf("[ POOLED   ] one keyframe: %d matches (%s); pooled %d views: %d matches, %d inliers (%zu of its own), "
              "%.4f m / %.3f deg from the truth, yaw sigma %.3f deg\n",
              single.correspondences, single.success ? "found" : "not found", pooled.views, pooled.correspondences,
              pooled.refined_inliers, pooled.matches.size(),
              (pooled.T_w_c.translation() - T_w_c_true.translation()).norm(), rotationError_deg(pooled.T_w_c, T_w_c_true),
              pooled.yaw_sigma_rad * 180.0 / M_PI);
  // The keyframe alone: fewer matches than a rejoin accepts (Loop.MinInliers 20), by either search.
  EXPECT_LT(single.correspondences, 20);
  EXPECT_LT(alone.refined_inliers, 20);
  EXPECT_EQ(alone.views, 1);
  // The window: every view takes part, enough inliers, the true pose.
  ASSERT_TRUE(pooled.success);
  EXPECT_EQ(pooled.views, kWindow);
  EXPECT_GE(pooled.refined_inliers, 40);
  EXPECT_LE(pooled.refined_inliers, pooled.correspondences);
  EXPECT_LT((pooled.T_w_c.translation() - T_w_c_true.translation()).norm(), 0.005);
  EXPECT_LT(rotationError_deg(pooled.T_w_c, T_w_c_true), 0.05);
  // The yaw is fixed well enough to correct a map by (the rejoin's limit is 0.5 deg).
  EXPECT_TRUE(std::isfinite(pooled.yaw_sigma_rad));
  EXPECT_LT(pooled.yaw_sigma_rad * 180.0 / M_PI, 0.5);
  // The matches of the keyframe placed are its own keypoints, matched to the target's points.
  ASSERT_FALSE(pooled.matches.empty());
  for (const auto& [keypoint, point] : pooled.matches) {
    EXPECT_GE(keypoint, 0);
    EXPECT_LT(keypoint, scene.window.front()->numKeypoints());
    EXPECT_NE(scene.target->mapPoint(point), nullptr);
  }
  ASSERT_NE(pooled.nearest_keyframe, nullptr);
  EXPECT_EQ(pooled.nearest_keyframe->mapId(), scene.target->id());
  EXPECT_NEAR(pooled.distance_m, (pooled.T_w_c.translation() - T_w_c_pred.translation()).norm(), 1e-12);
}

TEST(PooledPlaceMatch, WithTheRotationHeldOnlyTheTranslationIsSolved) {
  Scene scene;
  const SE3 T_w_c_true = truePose_T_w_b(scene.steps.front());
  // The prediction's rotation is right (the gyro knew it), its position 0.14 m off.
  const SE3 T_w_c_pred(T_w_c_true.quaternion(), T_w_c_true.translation() + Vec3(0.12, -0.07, 0.02));
  // The window keeps its relative poses: only the first keyframe's prediction matters.
  const GuidedPlaceMatch held = pooledPlaceMatch(scene.window, *scene.target, T_w_c_pred, searchOptions(), true);
  ASSERT_TRUE(held.success);
  EXPECT_GE(held.refined_inliers, 40);
  EXPECT_LT(rotationError_deg(held.T_w_c, T_w_c_pred), 1e-9);
  EXPECT_LT((held.T_w_c.translation() - T_w_c_true.translation()).norm(), 0.005);
  EXPECT_EQ(held.yaw_sigma_rad, std::numeric_limits<double>::infinity());
}

TEST(PooledPlaceMatch, OutsideTheGateThereIsNoPlace) {
  Scene scene;
  GuidedPlaceMatchOptions options = searchOptions();
  options.sigma_position_m = 0.02;  // 3 sigma = 6 cm, the world is 15 cm off
  options.min_radius_px = 60.0;     // the windows still reach the points
  const GuidedPlaceMatch pooled = pooledPlaceMatch(scene.window, *scene.target, scene.window.front()->T_w_c(), options);
  // The place is found (the same inliers as in the wide gate), then rejected by the gate.
  EXPECT_GE(pooled.refined_inliers, 40);
  EXPECT_GT(pooled.distance_m, 3.0 * options.sigma_position_m);
  EXPECT_FALSE(pooled.success);
  EXPECT_TRUE(pooled.matches.empty());
}

TEST(PooledPlaceMatch, TheWindowIsTheKeyFrameAndItsCovisiblesOfItsOwnMap) {
  map::Atlas atlas(world().vocabulary->numWords());
  SceneBuilder lap(atlas, SE3());
  for (int step = 0; step < 8; ++step) lap.add(step);
  const auto& kfs = lap.keyFrames();
  const map::Map& map = *atlas.map(kfs.back()->mapId());
  const std::vector<std::shared_ptr<map::KeyFrame>> window = poolingWindow(kfs.back(), map, 3);
  ASSERT_EQ(window.size(), 3u);
  EXPECT_EQ(window.front(), kfs.back());
  const std::vector<map::KeyFrameId> best = kfs.back()->bestCovisibles(2);
  ASSERT_EQ(best.size(), 2u);
  EXPECT_EQ(window[1]->id(), best[0]);
  EXPECT_EQ(window[2]->id(), best[1]);
  EXPECT_EQ(poolingWindow(kfs.back(), map, 1).size(), 1u);
  // A bad keyframe is left out.
  ASSERT_TRUE(atlas.map(kfs.back()->mapId())->eraseKeyFrame(window[1]->id()));
  for (const auto& kf : poolingWindow(kfs.back(), map, 8)) EXPECT_FALSE(kf->isBad());
}

}  // namespace
}  // namespace ltlo::loop
