// The size of local BA's problem on a revisited place (issue 32): 30 keyframes, as laps over one
// spot leave them, all see the same 60 points. LocalMapping.MaxFixedObservationsPerPoint and
// LocalMapping.MaxFixedObservationRatio bound the observations each point takes from the fixed
// keyframes, so the problem stops growing with the laps, and the optimised keyframes still return to
// their true poses (noise-free observations).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <random>

#include "../../src/mapping/local_window_ba.h"
#include "ltlo/map/map.h"

namespace ltlo::mapping {
namespace {

constexpr int kKeyFrames = 30;
constexpr int kPoints = 60;
constexpr int kWindow = 5;  ///< keyframes of the window (the map's gauge among them is held)

PinholeCamera qvgaCamera() { return PinholeCamera(262.5, 262.5, 159.5, 119.5, 320, 240); }
std::vector<float> levelSigma2() { return {1.0f, 1.44f, 2.0736f, 2.985984f}; }

/// The true pose of keyframe n (camera = body): a few cm apart along x, turned slightly.
SE3 truePose(int n) {
  return SE3(Quat(Eigen::AngleAxisd(0.01 * n, Vec3::UnitY())), Vec3(0.02 * n, 0.005 * (n % 3), 0.0));
}

/// kKeyFrames keyframes seeing the same kPoints points (exact projections and depths, octave 0),
/// all connected in the covisibility graph.
/// With `own_points_per_fixed`, each keyframe outside the newest kWindow + 1 also sees that many
/// points of its own, which the window does not: Eq. 56's probe points.
struct RevisitedSpot {
  explicit RevisitedSpot(int own_points_per_fixed = 0) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(40.0, 280.0), v(30.0, 210.0), z(2.0, 3.0);
    const PinholeCamera camera = qvgaCamera();
    std::vector<Vec3> points_w;
    for (int k = 0; k < kPoints; ++k) points_w.push_back(camera.backProject(Vec2(u(rng), v(rng)), z(rng)));
    const int with_own = kKeyFrames - kWindow - 1;
    std::vector<std::vector<Vec3>> own_w(static_cast<std::size_t>(with_own));
    for (auto& own : own_w) {
      for (int j = 0; j < own_points_per_fixed; ++j) own.push_back(camera.backProject(Vec2(u(rng), v(rng)), z(rng)));
    }
    for (int n = 0; n < kKeyFrames; ++n) {
      const SE3 T_w_b = truePose(n);
      features::OrbFeatures features;
      std::vector<float> depths;
      std::vector<Vec3> seen_w = points_w;
      if (n < with_own) {
        const std::vector<Vec3>& own = own_w[static_cast<std::size_t>(n)];
        seen_w.insert(seen_w.end(), own.begin(), own.end());
      }
      for (const Vec3& p_w : seen_w) {
        const Vec3 p_c = T_w_b.inverse() * p_w;
        const Vec2 uv = camera.project(p_c);
        features::Keypoint kp;
        kp.x_px = static_cast<float>(uv.x());
        kp.y_px = static_cast<float>(uv.y());
        features.keypoints.push_back(kp);
        features.descriptors.push_back(features::Descriptor{});
        depths.push_back(static_cast<float>(p_c.z()));
      }
      map::Frame frame(0.5 * n, camera, SE3(), std::move(features), std::move(depths), {1.0f, 1.2f, 1.44f, 1.728f});
      frame.setPose_T_w_b(T_w_b);
      keyframes.push_back(map.createKeyFrame(frame));
    }
    for (int k = 0; k < kPoints; ++k) {
      auto point = map.createMapPoint(points_w[static_cast<std::size_t>(k)], keyframes.front()->id());
      for (const auto& kf : keyframes) map.addObservation(*kf, k, *point);
    }
    for (int n = 0; n < with_own; ++n) {
      const auto& kf = keyframes[static_cast<std::size_t>(n)];
      for (int j = 0; j < own_points_per_fixed; ++j) {
        auto point = map.createMapPoint(own_w[static_cast<std::size_t>(n)][static_cast<std::size_t>(j)], kf->id());
        map.addObservation(*kf, kPoints + j, *point);
      }
    }
    for (const auto& kf : keyframes) map.updateConnections(*kf);
  }
  map::Map map;
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
};

struct CapResult {
  WindowBaStats stats;
  double largest_error_m = 0.0;  ///< optimised keyframes' position error after the BA
  SE3 pose_after;                ///< the newest keyframe's pose after the BA
};

/// Visual local BA around the newest keyframe, moved 3 cm off the truth first.
CapResult runWindow(std::size_t max_fixed_observations_per_point, double max_fixed_observation_ratio = 0.0) {
  RevisitedSpot spot;
  WindowBaOptions options;
  options.window_size = kWindow;
  options.max_fixed_keyframes = 50;
  options.max_fixed_observations_per_point = max_fixed_observations_per_point;
  options.max_fixed_observation_ratio = max_fixed_observation_ratio;
  options.robust = false;
  options.bf_px_m = 262.5 * 0.5;
  const auto& newest = spot.keyframes.back();
  newest->setPose_T_w_b(SE3(newest->T_w_b().quaternion(), newest->T_w_b().translation() + Vec3(0.03, -0.02, 0.01)));
  CapResult result;
  result.stats = localWindowBundleAdjust(spot.map, spot.keyframes.back(), options, levelSigma2());
  for (int n = 0; n < kKeyFrames; ++n) {
    const auto& kf = spot.keyframes[static_cast<std::size_t>(n)];
    result.largest_error_m =
        std::max(result.largest_error_m, (kf->T_w_b().translation() - truePose(n).translation()).norm());
  }
  result.pose_after = spot.keyframes.back()->T_w_b();
  return result;
}

TEST(LocalBaProblemSize, FixedObservationsPerPointAreCapped) {
  const CapResult all = runWindow(0);
  const CapResult capped = runWindow(4);
  std::printf("local BA: %d optimised + %d fixed keyframes, %d points; observations %d uncapped, %d with 4 fixed per "
              "point; largest position error after it %.2e / %.2e m\n",
              all.stats.optimised_keyframes, all.stats.fixed_keyframes, all.stats.points, all.stats.observations,
              capped.stats.observations, all.largest_error_m, capped.largest_error_m);
  ASSERT_EQ(all.stats.points, kPoints);
  ASSERT_EQ(all.stats.optimised_keyframes + all.stats.fixed_keyframes, kKeyFrames);
  // Uncapped every point carries an observation from every keyframe; capped, from the window's
  // keyframes and four fixed observers.
  EXPECT_EQ(all.stats.observations, kPoints * kKeyFrames);
  EXPECT_EQ(capped.stats.points, kPoints);
  EXPECT_EQ(capped.stats.fixed_keyframes, all.stats.fixed_keyframes);
  EXPECT_EQ(capped.stats.observations, kPoints * (kWindow + 4));
  // Both recover the true poses (exact data): the cap drops redundant constraints only.
  EXPECT_LT(all.largest_error_m, 1e-4);
  EXPECT_LT(capped.largest_error_m, 1e-4);
}

// LocalMapping.MaxFixedObservationRatio: a window whose fixed observations fit the ratio to the
// optimised keyframes' observations is left as it is (the same problem, the same result to the bit);
// one that does not gets the largest per-point limit that fits (at least one), and with a per-point
// limit as well the smaller of the two counts.
TEST(LocalBaProblemSize, FixedObservationRatioLowersThePerPointLimitOnlyWhenExceeded) {
  constexpr int kFixedPerPoint = kKeyFrames - kWindow;  // 25 fixed observers of every point
  constexpr double kWindowObservations = kPoints * kWindow;
  const CapResult all = runWindow(0);
  ASSERT_EQ(all.stats.fixed_observations, kPoints * kFixedPerPoint);
  ASSERT_EQ(all.stats.observations - all.stats.fixed_observations, kPoints * kWindow);
  EXPECT_EQ(all.stats.fixed_observation_limit, 0);

  const CapResult fits = runWindow(0, kFixedPerPoint / static_cast<double>(kWindow));  // exactly 5
  EXPECT_EQ(fits.stats.fixed_observation_limit, 0);
  EXPECT_EQ(fits.stats.observations, all.stats.observations);
  EXPECT_TRUE(fits.pose_after.translation() == all.pose_after.translation());
  EXPECT_TRUE(fits.pose_after.quaternion().coeffs() == all.pose_after.quaternion().coeffs());

  const CapResult one_short = runWindow(0, (kPoints * kFixedPerPoint - 1) / kWindowObservations);
  EXPECT_EQ(one_short.stats.fixed_observation_limit, kFixedPerPoint - 1);
  EXPECT_EQ(one_short.stats.fixed_observations, kPoints * (kFixedPerPoint - 1));

  const CapResult seven = runWindow(0, 7.5 / kWindow);  // 7.5 a point
  EXPECT_EQ(seven.stats.fixed_observation_limit, 7);
  EXPECT_EQ(seven.stats.fixed_observations, kPoints * 7);
  EXPECT_EQ(seven.stats.observations, kPoints * (kWindow + 7));
  EXPECT_LT(seven.largest_error_m, 1e-4);

  const CapResult tiny = runWindow(0, 0.01);  // below one a point: one a point all the same
  EXPECT_EQ(tiny.stats.fixed_observation_limit, 1);
  EXPECT_EQ(tiny.stats.fixed_observations, kPoints);
  EXPECT_LT(tiny.largest_error_m, 1e-4);

  EXPECT_EQ(runWindow(4, 7.5 / kWindow).stats.fixed_observation_limit, 4);  // the per-point limit is smaller
  EXPECT_EQ(runWindow(9, 7.5 / kWindow).stats.fixed_observation_limit, 7);  // the ratio's is
  EXPECT_EQ(runWindow(9, 0.0).stats.fixed_observation_limit, 9);
}

// LocalMapping.MaxProbePointRatio: the fixed keyframes' own points (which the window does not see)
// become Eq. 56's probe points, at most the ratio times the window's points; below the cap the
// window and its result are those without one, to the bit.
TEST(LocalBaProblemSize, ProbePointsAreCappedByTheirRatioToTheWindowsPoints) {
  constexpr int kOwn = 6;
  constexpr int kProbes = (kKeyFrames - kWindow - 1) * kOwn;  // own points of the 24 oldest keyframes
  auto run = [](double max_probe_point_ratio) {
    RevisitedSpot spot(kOwn);
    WindowBaOptions options;
    options.window_size = kWindow;
    options.max_fixed_keyframes = 50;
    options.max_probe_point_ratio = max_probe_point_ratio;
    options.robust = true;
    options.bf_px_m = 262.5 * 0.5;
    const auto& newest = spot.keyframes.back();
    newest->setPose_T_w_b(
        SE3(newest->T_w_b().quaternion(), newest->T_w_b().translation() + Vec3(0.03, -0.02, 0.01)));
    CapResult result;
    result.stats = localWindowBundleAdjust(spot.map, newest, options, levelSigma2());
    result.pose_after = newest->T_w_b();
    result.largest_error_m = (newest->T_w_b().translation() - truePose(kKeyFrames - 1).translation()).norm();
    return result;
  };
  const CapResult all = run(0.0);
  // Each own point is a window point (its keyframe is in the window) or a probe point.
  ASSERT_EQ(all.stats.points + all.stats.probe_points, kPoints + kProbes);
  ASSERT_GT(all.stats.probe_points, all.stats.points);  // so a ratio of 1 binds
  const CapResult loose = run(10.0);                    // not reached
  EXPECT_EQ(loose.stats.probe_points, all.stats.probe_points);
  EXPECT_TRUE(loose.pose_after.translation() == all.pose_after.translation());
  EXPECT_TRUE(loose.pose_after.quaternion().coeffs() == all.pose_after.quaternion().coeffs());
  EXPECT_EQ(run(1.0).stats.probe_points, all.stats.points);
  EXPECT_EQ(run(0.5).stats.probe_points, all.stats.points / 2);
  const CapResult capped = run(1.0);
  EXPECT_LT(all.largest_error_m, 1e-4);
  EXPECT_LT(capped.largest_error_m, 1e-4);
}

}  // namespace
}  // namespace ltlo::mapping
