// Full vision-only BA on a synthetic map: exact RGB-D observations, perturbed poses and points.
#include "ltlo/loop/global_ba.h"

#include <gtest/gtest.h>

#include <random>

namespace ltlo::loop {
namespace {

constexpr int kNumKeyFrames = 6;
constexpr int kNumPoints = 80;

TEST(GlobalBundleAdjustment, RecoversPerturbedPosesAndPoints) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> lateral(-1.5, 1.5), depth(3.0, 5.0);
  std::normal_distribution<double> noise(0.0, 1.0);
  const PinholeCamera camera(525.0, 525.0, 319.5, 239.5, 640, 480);
  std::vector<Vec3> p_w_true;
  for (int i = 0; i < kNumPoints; ++i) p_w_true.emplace_back(lateral(rng), lateral(rng), depth(rng));
  std::vector<SE3> T_w_b_true;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    T_w_b_true.emplace_back(so3Exp(Vec3(0.0, 0.03 * k, 0.0)), Vec3(0.1 * k, 0.02 * k, 0.0));
  }

  map::Map map;
  std::vector<std::shared_ptr<map::KeyFrame>> kfs;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    features::OrbFeatures features;
    std::vector<float> depths;
    for (const Vec3& p_w : p_w_true) {
      const Vec3 p_c = T_w_b_true[static_cast<std::size_t>(k)].inverse() * p_w;
      const Vec2 uv = camera.project(p_c);
      features::Keypoint kp;
      kp.x_px = static_cast<float>(uv.x());
      kp.y_px = static_cast<float>(uv.y());
      features.keypoints.push_back(kp);
      features.descriptors.push_back({});
      depths.push_back(static_cast<float>(p_c.z()));
    }
    map::Frame frame(0.1 * k, camera, SE3(), std::move(features), std::move(depths), {1.0f, 1.2f});
    const Vec6 perturbation = k == 0 ? Vec6::Zero().eval()
                                     : (Vec6() << 0.01 * noise(rng), 0.01 * noise(rng), 0.01 * noise(rng),
                                        0.03 * noise(rng), 0.03 * noise(rng), 0.03 * noise(rng))
                                           .finished();
    frame.setPose_T_w_b(T_w_b_true[static_cast<std::size_t>(k)] * SE3::exp(perturbation));
    kfs.push_back(map.createKeyFrame(frame));
  }
  std::vector<std::shared_ptr<map::MapPoint>> points;
  for (int i = 0; i < kNumPoints; ++i) {
    const Vec3 p_w = p_w_true[static_cast<std::size_t>(i)] + 0.03 * Vec3(noise(rng), noise(rng), noise(rng));
    points.push_back(map.createMapPoint(p_w, kfs[0]->id()));
    for (const std::shared_ptr<map::KeyFrame>& kf : kfs) ASSERT_TRUE(map.addObservation(*kf, i, *points.back()));
  }

  auto errors = [&] {
    double pose = 0.0, point = 0.0;
    for (int k = 0; k < kNumKeyFrames; ++k) {
      pose += (kfs[static_cast<std::size_t>(k)]->T_w_b().translation() -
               T_w_b_true[static_cast<std::size_t>(k)].translation())
                  .norm();
    }
    for (int i = 0; i < kNumPoints; ++i) {
      point += (points[static_cast<std::size_t>(i)]->p_w() - p_w_true[static_cast<std::size_t>(i)]).norm();
    }
    return std::make_pair(pose / kNumKeyFrames, point / kNumPoints);
  };
  const auto [pose_before, point_before] = errors();
  const GlobalBaResult result = runGlobalBundleAdjustment(map);
  const auto [pose_after, point_after] = errors();
  std::printf(
      "[ GBA      ] %d keyframes, %d points, %d observations, %d outliers: mean keyframe error %.2e -> %.2e m, "
      "mean point error %.2e -> %.2e m\n",
      result.keyframes, result.points, result.observations, result.outliers, pose_before, pose_after, point_before,
      point_after);
  EXPECT_EQ(result.observations, kNumKeyFrames * kNumPoints);
  EXPECT_EQ(result.outliers, 0);
  EXPECT_LT(pose_after, 1e-4);
  EXPECT_LT(point_after, 1e-4);
  EXPECT_LT(1e-3, pose_before);
}

/// Mean keyframe translation error (m) after a full BA of a map whose first kNumPoints / 2 points
/// ride on a box carried with the camera (seen where they were in keyframe 0 in every keyframe),
/// those points with static score `box_beta`; the keyframes start at their true poses.
double poseErrorWithCarriedBox(double box_beta) {
  std::mt19937 rng(33);
  std::uniform_real_distribution<double> lateral(-1.5, 1.5), depth(3.0, 5.0);
  const PinholeCamera camera(525.0, 525.0, 319.5, 239.5, 640, 480);
  std::vector<Vec3> p_w_true;
  for (int i = 0; i < kNumPoints; ++i) p_w_true.emplace_back(lateral(rng), lateral(rng), depth(rng));
  std::vector<SE3> T_w_b_true;
  for (int k = 0; k < kNumKeyFrames; ++k) T_w_b_true.emplace_back(so3Exp(Vec3(0.0, 0.02 * k, 0.0)), Vec3(0.1 * k, 0.0, 0.0));
  auto isBox = [](int i) { return i < kNumPoints / 2; };
  map::Map map;
  std::vector<std::shared_ptr<map::KeyFrame>> kfs;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    features::OrbFeatures features;
    std::vector<float> depths;
    for (int i = 0; i < kNumPoints; ++i) {
      // A box point keeps its keyframe-0 camera coordinates: it moves with the camera.
      const SE3& T_w_b_seen = isBox(i) ? T_w_b_true[0] : T_w_b_true[static_cast<std::size_t>(k)];
      const Vec3 p_c = T_w_b_seen.inverse() * p_w_true[static_cast<std::size_t>(i)];
      const Vec2 uv = camera.project(p_c);
      features.keypoints.push_back(features::Keypoint{static_cast<float>(uv.x()), static_cast<float>(uv.y()), 0.0f, 0.0f, 0});
      features.descriptors.push_back({});
      depths.push_back(static_cast<float>(p_c.z()));
    }
    map::Frame frame(0.1 * k, camera, SE3(), std::move(features), std::move(depths), {1.0f, 1.2f});
    frame.setPose_T_w_b(T_w_b_true[static_cast<std::size_t>(k)]);
    kfs.push_back(map.createKeyFrame(frame));
  }
  for (int i = 0; i < kNumPoints; ++i) {
    const std::shared_ptr<map::MapPoint> point = map.createMapPoint(p_w_true[static_cast<std::size_t>(i)], kfs[0]->id());
    for (const std::shared_ptr<map::KeyFrame>& kf : kfs) EXPECT_TRUE(map.addObservation(*kf, i, *point));
    if (isBox(i)) point->setBeta(box_beta);
  }
  runGlobalBundleAdjustment(map);
  double error_m = 0.0;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    error_m += (kfs[static_cast<std::size_t>(k)]->T_w_b().translation() - T_w_b_true[static_cast<std::size_t>(k)].translation()).norm();
  }
  return error_m / kNumKeyFrames;
}

TEST(GlobalBundleAdjustment, DynamicPointsCarryNoWeight) {
  // beta * gamma weighs each observation (Eq. 53): dynamic points (beta 0) leave the poses alone.
  const double error_dynamic_m = poseErrorWithCarriedBox(0.0);
  const double error_static_m = poseErrorWithCarriedBox(1.0);
  std::printf("[ GBA      ] carried box: mean keyframe error %.2e m with beta 0 on its points, %.2e m with beta 1\n",
              error_dynamic_m, error_static_m);
  EXPECT_LT(error_dynamic_m, 1e-4);
  EXPECT_GT(error_static_m, 1e-2);
}

TEST(GlobalBundleAdjustment, AStopRequestDiscardsTheResult) {
  map::Map map;
  const PinholeCamera camera(525.0, 525.0, 319.5, 239.5, 640, 480);
  std::vector<std::shared_ptr<map::KeyFrame>> kfs;
  for (int k = 0; k < 2; ++k) {
    features::OrbFeatures features;
    std::vector<float> depths;
    for (int i = 0; i < 10; ++i) {
      features.keypoints.push_back(features::Keypoint{static_cast<float>(100 + 20 * i), 200.0f, 0.0f, 0.0f, 0});
      features.descriptors.push_back({});
      depths.push_back(3.0f);
    }
    map::Frame frame(0.1 * k, camera, SE3(), std::move(features), std::move(depths), {1.0f, 1.2f});
    frame.setPose_T_w_b(SE3(Quat::Identity(), Vec3(0.1 * k, 0.0, 0.0)));
    kfs.push_back(map.createKeyFrame(frame));
  }
  for (int i = 0; i < 10; ++i) {
    const auto point = map.createMapPoint(Vec3(0.01 * i, 0.0, 3.0), kfs[0]->id());
    ASSERT_TRUE(map.addObservation(*kfs[0], i, *point));
    ASSERT_TRUE(map.addObservation(*kfs[1], i, *point));
  }
  const std::atomic<bool> stop{true};
  GlobalBaOptions options;
  options.stop_flag = &stop;
  const GlobalBaSolution solution = optimizeGlobalBundleAdjustment(map, options);
  EXPECT_FALSE(solution.valid);
  const std::uint64_t version = map.version();
  EXPECT_EQ(applyGlobalBundleAdjustment(map, solution), 0);
  EXPECT_EQ(map.version(), version);
  EXPECT_EQ(kfs[1]->T_w_b().translation(), Vec3(0.1, 0.0, 0.0));
}

TEST(GlobalBundleAdjustment, ApplyMovesKeyFramesAndPointsCreatedDuringTheRunWithTheirParent) {
  const PinholeCamera camera(525.0, 525.0, 319.5, 239.5, 640, 480);
  std::mt19937 rng(37);
  std::uniform_real_distribution<double> lateral(-1.0, 1.0), depth(3.0, 4.0);
  std::vector<Vec3> p_w_true;
  for (int i = 0; i < kNumPoints; ++i) p_w_true.emplace_back(lateral(rng), lateral(rng), depth(rng));
  auto frameAt = [&](const SE3& T_w_b_true, const SE3& T_w_b_estimate) {
    features::OrbFeatures features;
    std::vector<float> depths;
    for (const Vec3& p_w : p_w_true) {
      const Vec3 p_c = T_w_b_true.inverse() * p_w;
      const Vec2 uv = camera.project(p_c);
      features::Keypoint kp;
      kp.x_px = static_cast<float>(uv.x());
      kp.y_px = static_cast<float>(uv.y());
      features.keypoints.push_back(kp);
      features.descriptors.push_back({});
      depths.push_back(static_cast<float>(p_c.z()));
    }
    // Free keypoints for the points created later (their pixels do not matter here).
    for (int i = 0; i < kNumPoints / 2; ++i) {
      features.keypoints.push_back(features::Keypoint{});
      features.descriptors.push_back({});
      depths.push_back(2.0f);
    }
    map::Frame frame(0.0, camera, SE3(), std::move(features), std::move(depths), {1.0f, 1.2f});
    frame.setPose_T_w_b(T_w_b_estimate);
    return frame;
  };
  map::Map map;
  const SE3 T_w_b0(so3Exp(Vec3(0.0, 0.0, 0.0)), Vec3::Zero());
  const SE3 T_w_b1_true(so3Exp(Vec3(0.0, 0.05, 0.0)), Vec3(0.2, 0.0, 0.0));
  const SE3 offset = SE3::exp((Vec6() << 0.0, 0.02, 0.0, 0.05, -0.03, 0.02).finished());
  const auto kf0 = map.createKeyFrame(frameAt(T_w_b0, T_w_b0));
  const auto kf1 = map.createKeyFrame(frameAt(T_w_b1_true, T_w_b1_true * offset));
  for (int i = 0; i < kNumPoints; ++i) {
    const auto point = map.createMapPoint(p_w_true[static_cast<std::size_t>(i)], kf0->id());
    ASSERT_TRUE(map.addObservation(*kf0, i, *point));
    ASSERT_TRUE(map.addObservation(*kf1, i, *point));
  }
  map.updateConnections(*kf1);
  const GlobalBaSolution solution = optimizeGlobalBundleAdjustment(map);
  ASSERT_TRUE(solution.valid);
  EXPECT_LT((kf1->T_w_b().translation() - (T_w_b1_true * offset).translation()).norm(), 1e-12);  // not written yet

  // Local mapping adds meanwhile a keyframe kf2 (from kf1's old estimate) and points created by kf1
  // that kf2 sees too; kf2's parent is kf1.
  const SE3 T_b1_b2(so3Exp(Vec3(0.0, 0.03, 0.0)), Vec3(0.1, 0.0, 0.0));
  const auto kf2 = map.createKeyFrame(frameAt(T_w_b1_true * T_b1_b2, kf1->T_w_b() * T_b1_b2));
  std::vector<std::pair<std::shared_ptr<map::MapPoint>, Vec3>> new_points;  // with p_w true
  for (int i = 0; i < kNumPoints / 2; ++i) {
    const Vec3 p_b1(lateral(rng), lateral(rng), depth(rng));
    const auto point = map.createMapPoint(kf1->T_w_b() * p_b1, kf1->id());
    ASSERT_TRUE(map.addObservation(*kf1, kNumPoints + i, *point));
    ASSERT_TRUE(map.addObservation(*kf2, kNumPoints + i, *point));
    new_points.emplace_back(point, T_w_b1_true * p_b1);
  }
  map.updateConnections(*kf2);
  ASSERT_EQ(kf2->parent(), kf1->id());
  const std::uint64_t version = map.version();
  EXPECT_EQ(applyGlobalBundleAdjustment(map, solution), 1);
  EXPECT_GT(map.version(), version);
  EXPECT_LT((kf1->T_w_b().translation() - T_w_b1_true.translation()).norm(), 1e-4);
  EXPECT_LT(((T_w_b1_true * T_b1_b2).inverse() * kf2->T_w_b()).translation().norm(), 1e-4);
  double max_point_error_m = 0.0;
  for (const auto& [point, p_w_true_new] : new_points) {
    max_point_error_m = std::max(max_point_error_m, (point->p_w() - p_w_true_new).norm());
  }
  EXPECT_LT(max_point_error_m, 1e-4);
}

// One keyframe sees a "box" (its right image half, cluster 1) whose points moved by 1.5 px since the
// others saw them: inside the chi2 gate, so only the static weight beta * gamma (thesis Eq. 53) keeps
// them from pulling the keyframe. Points of low beta stay out of the BA.
double poseErrorWithBoxGamma(double box_gamma, GlobalBaResult* result_out) {
  const PinholeCamera camera(525.0, 525.0, 319.5, 239.5, 640, 480);
  std::mt19937 rng(33);
  std::uniform_real_distribution<double> lateral(-1.5, 1.5), depth(3.0, 5.0);
  std::vector<Vec3> p_w_true;
  for (int i = 0; i < kNumPoints; ++i) p_w_true.emplace_back(lateral(rng), lateral(rng), depth(rng));
  map::Map map;
  std::vector<std::shared_ptr<map::KeyFrame>> kfs;
  std::vector<SE3> T_w_b_true;
  for (int k = 0; k < kNumKeyFrames; ++k) {
    T_w_b_true.emplace_back(so3Exp(Vec3(0.0, 0.03 * k, 0.0)), Vec3(0.1 * k, 0.02 * k, 0.0));
    const bool boxed = k == kNumKeyFrames - 1;
    features::OrbFeatures features;
    std::vector<float> depths;
    for (const Vec3& p_w : p_w_true) {
      const Vec3 p_c = T_w_b_true.back().inverse() * p_w;
      Vec2 uv = camera.project(p_c);
      if (boxed && uv.x() >= 320.0) uv.x() += 1.5;
      features.keypoints.push_back(features::Keypoint{static_cast<float>(uv.x()), static_cast<float>(uv.y()), 0.0f, 0.0f, 0});
      features.descriptors.push_back({});
      depths.push_back(static_cast<float>(p_c.z()));
    }
    map::Frame frame(0.1 * k, camera, SE3(), std::move(features), std::move(depths), {1.0f, 1.2f});
    if (boxed) {
      map::ClusterSegmentation segmentation;
      segmentation.labels = cv::Mat(480, 640, CV_8U, cv::Scalar(0));
      segmentation.labels.colRange(320, 640).setTo(1);
      segmentation.gamma = {1.0, box_gamma, 1.0};  // static background, the box, no depth
      frame.setSegmentation(segmentation, 0.01);
    }
    frame.setPose_T_w_b(T_w_b_true.back());
    kfs.push_back(map.createKeyFrame(frame));
  }
  for (int i = 0; i < kNumPoints; ++i) {
    const auto point = map.createMapPoint(p_w_true[static_cast<std::size_t>(i)], kfs[0]->id());
    for (const auto& kf : kfs) EXPECT_TRUE(map.addObservation(*kf, i, *point));
    if (i < 5) point->setBeta(0.2);  // found dynamic: left out (LocalMapping.MinPointBeta = 0.5)
  }
  const GlobalBaResult result = runGlobalBundleAdjustment(map);
  if (result_out != nullptr) *result_out = result;
  return (kfs.back()->T_w_b().translation() - T_w_b_true.back().translation()).norm();
}

TEST(GlobalBundleAdjustment, StaticWeightsKeepAMovedBoxFromPullingTheKeyFrame) {
  GlobalBaResult weighted;
  const double error_weighted_m = poseErrorWithBoxGamma(0.05, &weighted);
  const double error_unweighted_m = poseErrorWithBoxGamma(1.0, nullptr);
  std::printf("[ GBA BETA ] keyframe seeing a moved box: error %.2e m with the box's gamma 0.05, %.2e m with gamma 1\n",
              error_weighted_m, error_unweighted_m);
  EXPECT_EQ(weighted.points, kNumPoints - 5);
  EXPECT_GT(error_unweighted_m, 2e-3);
  EXPECT_LT(error_weighted_m, 0.1 * error_unweighted_m);
}

}  // namespace
}  // namespace ltlo::loop
