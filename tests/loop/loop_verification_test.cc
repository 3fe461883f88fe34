// Loop detection and geometric verification through the map API: a candidate keyframe holding map
// points and a current keyframe seeing the same descriptors from a drifted pose (fixed seeds, tiny
// vocabulary trained on the test's own descriptors, no images).
#include <gtest/gtest.h>

#include <random>

#include "bow/vocabulary.h"
#include "ltlo/loop/loop_corrector.h"
#include "ltlo/loop/loop_detector.h"
#include "ltlo/loop/map_merger.h"
#include "ltlo/map/keyframe_database.h"

namespace ltlo::loop {
namespace {

constexpr int kNumKeypoints = 150;
constexpr int kNumMapPoints = 100;
constexpr int kNumWrong = 30;  // current keypoints whose 3-D point is not the candidate's (outliers)

const PinholeCamera kCamera(525.0, 525.0, 319.5, 239.5, 640, 480);

struct LoopScene {
  map::Map map;
  std::shared_ptr<map::KeyFrame> candidate;
  std::shared_ptr<map::KeyFrame> current;
  SE3 T_w_b_current_true;
  std::unique_ptr<bow::Vocabulary> vocabulary;
};

/// The candidate goes into `candidate_map`, the current keyframe into `current_map`.
void buildLoopScene(LoopScene& scene, map::Map& candidate_map, map::Map& current_map) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(20.0f, 620.0f), v(20.0f, 460.0f), depth(1.0f, 4.0f);
  std::uniform_int_distribution<std::uint64_t> bits;
  const SE3 T_w_b_candidate(so3Exp(Vec3(0.0, 0.1, 0.0)), Vec3(0.0, 0.0, 0.0));
  scene.T_w_b_current_true = SE3(so3Exp(Vec3(0.0, 0.2, 0.05)), Vec3(0.15, -0.05, 0.1));
  const SE3 T_w_b_current_drifted =
      SE3::exp((Vec6() << 0.0, 0.0, 0.08, 0.3, 0.2, 0.0).finished()) * scene.T_w_b_current_true;

  features::OrbFeatures candidate_features, current_features;
  std::vector<float> candidate_depths, current_depths;
  std::vector<Vec3> p_w(kNumKeypoints);
  for (int i = 0; i < kNumKeypoints; ++i) {
    const features::Descriptor d{bits(rng), bits(rng), bits(rng), bits(rng)};
    features::Keypoint kp;
    kp.x_px = u(rng);
    kp.y_px = v(rng);
    const float z = depth(rng);
    candidate_features.keypoints.push_back(kp);
    candidate_features.descriptors.push_back(d);
    candidate_depths.push_back(z);
    p_w[static_cast<std::size_t>(i)] = T_w_b_candidate * kCamera.backProject(Vec2(kp.x_px, kp.y_px), z);
    // The current keyframe sees the same point (or, for the first kNumWrong, another place).
    Vec3 p_c = scene.T_w_b_current_true.inverse() * p_w[static_cast<std::size_t>(i)];
    if (i < kNumWrong) p_c = kCamera.backProject(Vec2(u(rng), v(rng)), depth(rng));
    const Vec2 uv = kCamera.project(p_c);
    features::Keypoint current_kp;
    current_kp.x_px = static_cast<float>(uv.x());
    current_kp.y_px = static_cast<float>(uv.y());
    current_features.keypoints.push_back(current_kp);
    current_features.descriptors.push_back(d);
    current_depths.push_back(static_cast<float>(p_c.z()));
  }
  // Trained with unrelated images too so the words get non-zero IDF weights.
  std::vector<std::vector<features::Descriptor>> training{candidate_features.descriptors};
  for (int image = 0; image < 4; ++image) {
    training.emplace_back();
    for (int i = 0; i < kNumKeypoints; ++i) training.back().push_back({bits(rng), bits(rng), bits(rng), bits(rng)});
  }
  scene.vocabulary =
      std::make_unique<bow::Vocabulary>(bow::Vocabulary::train(training, bow::TrainOptions{4, 3, 5, 1, 1, 0, {}}));
  const std::vector<float> scales{1.0f, 1.2f, 1.44f, 1.728f};
  map::Frame candidate(0.0, kCamera, SE3(), candidate_features, candidate_depths, scales);
  candidate.setPose_T_w_b(T_w_b_candidate);
  candidate.computeBow(*scene.vocabulary);
  map::Frame current(10.0, kCamera, SE3(), current_features, current_depths, scales);
  current.setPose_T_w_b(T_w_b_current_drifted);
  current.computeBow(*scene.vocabulary);
  scene.candidate = candidate_map.createKeyFrame(candidate);
  scene.current = current_map.createKeyFrame(current);
  for (int i = 0; i < kNumMapPoints; ++i) {
    const std::shared_ptr<map::MapPoint> point =
        candidate_map.createMapPoint(p_w[static_cast<std::size_t>(i)], scene.candidate->id());
    ASSERT_TRUE(candidate_map.addObservation(*scene.candidate, i, *point));
  }
}

TEST(LoopVerification, RecoversTheCurrentPoseFromThreeDMatches) {
  LoopScene scene;
  buildLoopScene(scene, scene.map, scene.map);
  LoopOptions options;
  place::Se3RansacResult ransac;
  const std::optional<LoopClosure> loop = verifyLoop(*scene.current, *scene.candidate, scene.map, options, &ransac);
  ASSERT_TRUE(loop.has_value());
  const SE3 error = scene.T_w_b_current_true.inverse() * loop->T_w_b_current_corrected;
  std::printf("[ VERIFY   ] %zu inliers of %zu matches, pose error %.2e m / %.2e rad\n", loop->matches.size(),
              ransac.inliers.size(), error.translation().norm(), error.log().head<3>().norm());
  EXPECT_EQ(static_cast<int>(loop->matches.size()), kNumMapPoints - kNumWrong);
  EXPECT_LT(error.translation().norm(), 1e-6);
  EXPECT_LT(error.log().head<3>().norm(), 1e-6);
  for (const LoopMatch& m : loop->matches) EXPECT_GE(m.keypoint, kNumWrong);
}

TEST(LoopVerification, RejectsBelowTheMinimumInliers) {
  LoopScene scene;
  buildLoopScene(scene, scene.map, scene.map);
  LoopOptions options;
  options.min_inliers = kNumMapPoints - kNumWrong + 1;
  EXPECT_FALSE(verifyLoop(*scene.current, *scene.candidate, scene.map, options).has_value());
}

TEST(LoopDetector, NeedsThreeConsistentQueriesAndAStaticImage) {
  LoopScene scene;
  buildLoopScene(scene, scene.map, scene.map);
  map::KeyFrameDatabase database(scene.vocabulary->numWords());
  database.add(scene.candidate);
  LoopOptions options;
  LoopDetector detector(options);
  EXPECT_TRUE(detector.detect(*scene.current, scene.map, database).empty());
  EXPECT_TRUE(detector.detect(*scene.current, scene.map, database).empty());
  // A mostly dynamic image is not queried and leaves the consistency state alone.
  const std::vector<double> gamma = scene.current->gamma();
  scene.current->setGamma(std::vector<double>(gamma.size(), 0.0));
  EXPECT_TRUE(detector.detect(*scene.current, scene.map, database).empty());
  EXPECT_EQ(detector.consistency().maxCount(), 2);
  scene.current->setGamma(gamma);
  const std::vector<std::shared_ptr<map::KeyFrame>> found = detector.detect(*scene.current, scene.map, database);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0]->id(), scene.candidate->id());
}

TEST(MapMerger, MergesTheCurrentMapIntoTheRecognisedOne) {
  LoopScene scene;
  // The vocabulary is made by the scene; the atlas database is sized generously (unused here).
  map::Atlas atlas(100000);
  map::Map& old_map = atlas.activeMap();
  map::Map& new_map = atlas.createNewMap();
  buildLoopScene(scene, old_map, new_map);
  ASSERT_EQ(atlas.numMaps(), 2u);
  const std::optional<MergeResult> merged = mergeAtPlace(atlas, *scene.current, *scene.candidate, LoopOptions());
  ASSERT_TRUE(merged.has_value());
  const SE3 error = scene.T_w_b_current_true.inverse() * scene.current->T_w_b();
  std::printf("[ MERGE    ] %d inliers, %d points fused/added, current pose error after merge %.2e m / %.2e rad\n",
              merged->inliers, merged->correction.fused_points + merged->correction.added_observations,
              error.translation().norm(), error.log().head<3>().norm());
  EXPECT_EQ(atlas.numMaps(), 1u);
  EXPECT_EQ(scene.current->mapId(), old_map.id());
  EXPECT_EQ(merged->target, old_map.id());
  EXPECT_EQ(merged->correction.added_observations, kNumMapPoints - kNumWrong);
  EXPECT_LT(error.translation().norm(), 1e-6);
  EXPECT_LT(error.log().head<3>().norm(), 1e-6);
  // Same map now: a second merge is refused.
  EXPECT_FALSE(mergeAtPlace(atlas, *scene.current, *scene.candidate, LoopOptions()).has_value());
}

}  // namespace
}  // namespace ltlo::loop
