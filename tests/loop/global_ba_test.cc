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

}  // namespace
}  // namespace ltlo::loop
