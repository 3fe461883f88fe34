// Loop correction on a synthetic map: keyframes on a circle with drift accumulated over the second
// half, points shared by consecutive keyframes, a loop between the last and the first keyframe with
// the true relative pose (fixed seeds, no images).
#include "ltlo/loop/loop_corrector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "ltlo/map/map.h"

namespace ltlo::loop {
namespace {

constexpr int kNumKeyFrames = 30;
constexpr int kPointsPerTriple = 25;
constexpr int kNumKeypoints = 400;

map::Frame randomFrame(std::mt19937& rng, double t_s, const SE3& T_w_b) {
  std::uniform_real_distribution<float> x(0.0f, 639.0f), y(0.0f, 479.0f), depth(1.0f, 4.0f);
  std::uniform_int_distribution<std::uint64_t> bits;
  features::OrbFeatures features;
  std::vector<float> depths;
  for (int i = 0; i < kNumKeypoints; ++i) {
    features::Keypoint kp;
    kp.x_px = x(rng);
    kp.y_px = y(rng);
    features.keypoints.push_back(kp);
    features.descriptors.push_back({bits(rng), bits(rng), bits(rng), bits(rng)});
    depths.push_back(depth(rng));
  }
  map::Frame frame(t_s, PinholeCamera(525.0, 525.0, 319.5, 239.5, 640, 480), SE3(), std::move(features),
                   std::move(depths), {1.0f, 1.2f, 1.44f, 1.728f});
  frame.setPose_T_w_b(T_w_b);
  return frame;
}

SE3 circlePose(int k) {
  const double angle = 2.0 * M_PI * k / kNumKeyFrames;
  return SE3(so3Exp(Vec3(0.0, 0.0, angle + M_PI_2)), Vec3(3.0 * std::cos(angle), 3.0 * std::sin(angle), 0.0));
}

struct Scene {
  map::Map map;
  std::vector<std::shared_ptr<map::KeyFrame>> kfs;
  std::vector<SE3> T_w_b_true;
  std::vector<int> next_keypoint;
  /// Points with their true position and the loop-side points of keyframe 0.
  std::vector<std::pair<std::shared_ptr<map::MapPoint>, Vec3>> points;
};

/// Drift: every odometry step of the second half is off by `step_error`.
void buildScene(Scene& scene, const SE3& step_error) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> local(-1.0, 1.0);
  std::vector<SE3> T_w_b_drifted;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    scene.T_w_b_true.push_back(circlePose(k));
    if (k <= kNumKeyFrames / 2) {
      T_w_b_drifted.push_back(circlePose(k));
    } else {
      T_w_b_drifted.push_back(T_w_b_drifted.back() * circlePose(k - 1).inverse() * circlePose(k) * step_error);
    }
    scene.kfs.push_back(scene.map.createKeyFrame(randomFrame(rng, 0.1 * k, T_w_b_drifted.back())));
    scene.next_keypoint.push_back(0);
  }
  // Each point is created by keyframe k (at its drifted pose) and seen by k, k+1, k+2. Keyframes are
  // connected in insertion order as local mapping does (each one's parent is an older keyframe).
  std::vector<std::vector<std::shared_ptr<map::MapPoint>>> created(kNumKeyFrames);
  for (int k = 0; k < kNumKeyFrames; ++k) {
    map::KeyFrame& kf = *scene.kfs[static_cast<std::size_t>(k)];
    for (int older = std::max(0, k - 2); older < k; ++older) {
      for (const std::shared_ptr<map::MapPoint>& point : created[static_cast<std::size_t>(older)]) {
        ASSERT_TRUE(scene.map.addObservation(kf, scene.next_keypoint[k]++, *point));
      }
    }
    if (k + 2 < kNumKeyFrames) {
      for (int n = 0; n < kPointsPerTriple; ++n) {
        const Vec3 p_b(local(rng), local(rng), 2.0 + local(rng));
        const std::shared_ptr<map::MapPoint> point =
            scene.map.createMapPoint(T_w_b_drifted[static_cast<std::size_t>(k)] * p_b, kf.id());
        ASSERT_TRUE(scene.map.addObservation(kf, scene.next_keypoint[k]++, *point));
        created[static_cast<std::size_t>(k)].push_back(point);
        scene.points.emplace_back(point, scene.T_w_b_true[static_cast<std::size_t>(k)] * p_b);
      }
    }
    scene.map.updateConnections(kf);
  }
}

double endToStartError_m(const Scene& scene) {
  const SE3 estimate = scene.kfs.front()->T_w_b().inverse() * scene.kfs.back()->T_w_b();
  const SE3 truth = scene.T_w_b_true.front().inverse() * scene.T_w_b_true.back();
  return (estimate.translation() - truth.translation()).norm();
}

double meanPositionError_m(const Scene& scene) {
  double sum = 0.0;
  for (std::size_t k = 0; k < scene.kfs.size(); ++k) {
    sum += (scene.kfs[k]->T_w_b().translation() - scene.T_w_b_true[k].translation()).norm();
  }
  return sum / static_cast<double>(scene.kfs.size());
}

double meanPointError_m(const Scene& scene) {
  double sum = 0.0;
  int n = 0;
  for (const auto& [point, p_w_true] : scene.points) {
    if (point->isBad()) continue;
    sum += (point->p_w() - p_w_true).norm();
    ++n;
  }
  return sum / n;
}

TEST(LoopCorrector, EssentialGraphRemovesDrift) {
  Scene scene;
  buildScene(scene, SE3::exp((Vec6() << 0.0, 0.0, 0.01, 0.01, 0.005, 0.002).finished()));
  const double end_before = endToStartError_m(scene);
  const double mean_before = meanPositionError_m(scene);
  const double points_before = meanPointError_m(scene);

  // Loop side: keypoints of the last keyframe see points of the first keyframe (fused) or nothing
  // (new observations).
  map::KeyFrame& current = *scene.kfs.back();
  map::KeyFrame& first = *scene.kfs.front();
  LoopClosure loop;
  loop.current = current.id();
  loop.loop = first.id();
  loop.T_w_b_current_corrected = scene.T_w_b_true.back();  // the first keyframe is at its true pose
  for (int n = 0; n < 10; ++n) {
    loop.matches.push_back(LoopMatch{n, first.mapPoint(n)});                                    // holds a point: fuse
    loop.matches.push_back(LoopMatch{scene.next_keypoint.back() + n, first.mapPoint(10 + n)});  // free keypoint
  }
  const LoopCorrectionResult result = correctLoop(scene.map, loop);

  const double end_after = endToStartError_m(scene);
  const double mean_after = meanPositionError_m(scene);
  const double points_after = meanPointError_m(scene);
  std::printf(
      "[ LOOP     ] end-to-start error %.4f -> %.4f m (%.1fx), mean keyframe position error %.4f -> %.4f m "
      "(%.1fx), mean point error %.4f -> %.4f m; window %d, fused %d, added %d, %d edges, chi2 %.3g -> %.3g\n",
      end_before, end_after, end_before / end_after, mean_before, mean_after, mean_before / mean_after, points_before,
      points_after, result.window_size, result.fused_points, result.added_observations, result.graph_edges,
      result.initial_cost, result.final_cost);
  EXPECT_GT(end_before, 0.1);
  EXPECT_LT(end_after, end_before / 5.0);
  EXPECT_LT(mean_after, mean_before);
  EXPECT_LT(points_after, points_before);
  EXPECT_EQ(result.fused_points, 10);
  EXPECT_EQ(result.added_observations, 10);
  EXPECT_LT(result.final_cost, result.initial_cost);
  // The loop keyframe is the gauge; the loop edge is recorded on both ends.
  EXPECT_LT((first.T_w_b().translation() - scene.T_w_b_true.front().translation()).norm(), 1e-9);
  ASSERT_EQ(current.loopEdges().size(), 1u);
  EXPECT_EQ(current.loopEdges()[0], first.id());
  EXPECT_EQ(first.loopEdges()[0], current.id());
  EXPECT_GT(current.weight(first.id()), 0);
}

TEST(LoopCorrector, FourDofWithGravityTurnsVelocitiesAndKeepsRollAndPitch) {
  // The drift of the second half is a turn about gravity (-z) and a translation: what a 4-DoF
  // correction can remove. Each keyframe moves along its heading at 1 m/s (body velocity (1, 0, 0)
  // rotated by its drifted pose).
  Scene scene;
  buildScene(scene, SE3::exp((Vec6() << 0.0, 0.0, 0.01, 0.01, 0.005, 0.002).finished()));
  const Vec3 v_b(1.0, 0.0, 0.0);
  for (const std::shared_ptr<map::KeyFrame>& kf : scene.kfs) kf->setVelocity(kf->T_w_b().rotationMatrix() * v_b);
  auto velocityError = [&] {
    double worst = 0.0;
    for (std::size_t k = 0; k < scene.kfs.size(); ++k) {
      worst = std::max(worst, (scene.kfs[k]->v_w_b() - scene.T_w_b_true[k].rotationMatrix() * v_b).norm());
    }
    return worst;
  };
  const Vec3 up_w(0.0, 0.0, 1.0);
  std::vector<Vec3> up_in_body;
  for (const std::shared_ptr<map::KeyFrame>& kf : scene.kfs) up_in_body.push_back(kf->T_w_b().rotationMatrix().transpose() * up_w);
  const double end_before = endToStartError_m(scene);
  const double velocity_before = velocityError();

  map::KeyFrame& current = *scene.kfs.back();
  map::KeyFrame& first = *scene.kfs.front();
  LoopClosure loop;
  loop.current = current.id();
  loop.loop = first.id();
  // The place match also carries a small tilt error (0.3 deg): gravity says otherwise, so it is dropped.
  loop.T_w_b_current_corrected =
      SE3(so3ExpQuat(Vec3(0.005, 0.0, 0.0)) * scene.T_w_b_true.back().quaternion(), scene.T_w_b_true.back().translation());
  for (int n = 0; n < 10; ++n) loop.matches.push_back(LoopMatch{n, first.mapPoint(n)});
  LoopCorrectionOptions options;
  options.g_w = Vec3(0.0, 0.0, -9.81);
  const LoopCorrectionResult result = correctLoop(scene.map, loop, options);

  double tilt_change = 0.0, body_velocity_change = 0.0;
  for (std::size_t k = 0; k < scene.kfs.size(); ++k) {
    const Mat3 R_w_b = scene.kfs[k]->T_w_b().rotationMatrix();
    tilt_change = std::max(tilt_change, (R_w_b.transpose() * up_w - up_in_body[k]).norm());
    body_velocity_change = std::max(body_velocity_change, (R_w_b.transpose() * scene.kfs[k]->v_w_b() - v_b).norm());
  }
  const double end_after = endToStartError_m(scene);
  const double velocity_after = velocityError();
  std::printf("[ LOOP4DOF ] end-to-start error %.4f -> %.4f m, max velocity error %.3f -> %.4f m/s, roll/pitch change "
              "%.1e, body-frame velocity change %.1e, %d edges\n",
              end_before, end_after, velocity_before, velocity_after, tilt_change, body_velocity_change,
              result.graph_edges);
  EXPECT_GT(end_before, 0.1);
  EXPECT_LT(end_after, end_before / 5.0);
  EXPECT_LT(tilt_change, 1e-9);            // roll and pitch are observable through gravity: untouched
  EXPECT_LT(body_velocity_change, 1e-9);   // velocities turn with their poses
  EXPECT_GT(velocity_before, 0.05);
  // The graph spreads the heading error over the lap (as the positions, see EssentialGraphRemovesDrift).
  EXPECT_LT(velocity_after, velocity_before / 2.0);
}

TEST(LoopCorrector, LeavesADriftFreeMapInPlace) {
  Scene scene;
  buildScene(scene, SE3());
  LoopClosure loop;
  loop.current = scene.kfs.back()->id();
  loop.loop = scene.kfs.front()->id();
  loop.T_w_b_current_corrected = scene.T_w_b_true.back();
  correctLoop(scene.map, loop);
  EXPECT_LT(meanPositionError_m(scene), 1e-6);
  EXPECT_LT(meanPointError_m(scene), 1e-6);
}

}  // namespace
}  // namespace ltlo::loop
