// Atlas: a new map when tracking is lost, unique ids across maps, merging with an SE3.
#include <gtest/gtest.h>

#include "ltlo/map/atlas.h"
#include "map_test_util.h"

namespace ltlo::map {
namespace {

SE3 randomPose(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vec6 xi;
  for (int k = 0; k < 6; ++k) xi[k] = n(rng);
  return SE3::exp(xi);
}

TEST(Atlas, NewMapBecomesActiveAndIdsStayUnique) {
  Atlas atlas(/*num_words=*/16);
  Map& first = atlas.activeMap();
  EXPECT_EQ(atlas.numMaps(), 1u);
  test::SceneBuilder scene_first(first, 31);
  const auto kf0 = scene_first.addKeyFrame();
  const auto p0 = scene_first.share({kf0}, 3);

  Map& second = atlas.createNewMap();  // tracking lost
  EXPECT_NE(second.id(), first.id());
  EXPECT_EQ(atlas.activeMapId(), second.id());
  EXPECT_EQ(&atlas.activeMap(), &second);
  EXPECT_EQ(atlas.numMaps(), 2u);
  test::SceneBuilder scene_second(second, 32);
  const auto kf1 = scene_second.addKeyFrame();
  const auto p1 = scene_second.share({kf1}, 3);
  EXPECT_EQ(kf1->id(), KeyFrameId(kf0->id().value + 1));  // one id source for the whole atlas
  EXPECT_EQ(p1.front()->id(), MapPointId(p0.back()->id().value + 1));
  EXPECT_EQ(kf1->mapId(), second.id());
  EXPECT_EQ(second.originKeyFrames(), std::vector<KeyFrameId>{kf1->id()});
  EXPECT_EQ(first.numKeyFrames(), 1u);
}

TEST(Atlas, MergeTransformsEveryPoseAndPointExactly) {
  std::mt19937 rng(33);
  Atlas atlas(16);
  Map& target = atlas.activeMap();
  test::SceneBuilder target_scene(target, 34);
  const std::shared_ptr<KeyFrame> target_first = target_scene.addKeyFrame(randomPose(rng));
  for (int k = 1; k < 3; ++k) target_scene.addKeyFrame(randomPose(rng));
  Map& source = atlas.createNewMap();
  test::SceneBuilder source_scene(source, 35);
  std::vector<std::shared_ptr<KeyFrame>> source_kfs;
  for (int k = 0; k < 4; ++k) {
    source_kfs.push_back(source_scene.addKeyFrame(randomPose(rng)));
    source_kfs.back()->setVelocity(Vec3(0.1 * k, -0.2, 0.3));
  }
  const auto points = source_scene.share(source_kfs, 30);
  for (const auto& p : points) source.updateNormalAndDistances(*p);
  for (const auto& kf : source_kfs) source.updateConnections(*kf);

  struct Before {
    SE3 T_w_b;
    Vec3 v_w_b;
  };
  std::vector<Before> kf_before;
  for (const auto& kf : source_kfs) kf_before.push_back({kf->T_w_b(), kf->v_w_b()});
  std::vector<std::pair<Vec3, Vec3>> point_before;
  for (const auto& p : points) point_before.emplace_back(p->p_w(), p->normal_w());
  const std::uint64_t target_version = target.version();

  const SE3 T_target_source = randomPose(rng);
  atlas.mergeMaps(source.id(), target.id(), T_target_source);

  EXPECT_EQ(atlas.mapIds(), std::vector<MapId>{target.id()});
  EXPECT_EQ(atlas.activeMapId(), target.id());  // the source was active
  EXPECT_EQ(source.numKeyFrames(), 0u);
  EXPECT_EQ(source.numMapPoints(), 0u);
  EXPECT_EQ(target.numKeyFrames(), 7u);
  EXPECT_EQ(target.numMapPoints(), 30u);
  EXPECT_EQ(target.version(), target_version + 1);
  // Both first keyframes stay roots, but only the target's own holds the BAs' gauge: the source's
  // was placed by the merge transform, which the BAs must be free to correct.
  EXPECT_EQ(target.originKeyFrames().size(), 2u);
  EXPECT_EQ(target.gaugeKeyFrame(), target_first->id());
  const Mat3 R = T_target_source.rotationMatrix();
  for (std::size_t k = 0; k < source_kfs.size(); ++k) {
    const std::shared_ptr<KeyFrame> kf = target.keyFrame(source_kfs[k]->id());
    ASSERT_EQ(kf, source_kfs[k]);
    EXPECT_EQ(kf->mapId(), target.id());
    const SE3 expected = T_target_source * kf_before[k].T_w_b;
    EXPECT_LT((kf->T_w_b().matrix() - expected.matrix()).norm(), 1e-15);
    EXPECT_LT((kf->v_w_b() - R * kf_before[k].v_w_b).norm(), 1e-15);
    // The pose moved: the merge is not a no-op.
    EXPECT_GT((kf->T_w_b().translation() - kf_before[k].T_w_b.translation()).norm(), 1e-3);
  }
  for (std::size_t n = 0; n < points.size(); ++n) {
    EXPECT_LT((points[n]->p_w() - T_target_source * point_before[n].first).norm(), 1e-15);
    EXPECT_LT((points[n]->normal_w() - R * point_before[n].second).norm(), 1e-15);
  }
  // Links survive the move: covisibility and observations still resolve in the target map.
  EXPECT_EQ(source_kfs[1]->weight(source_kfs[0]->id()), 30);
  EXPECT_EQ(target.mapPoint(points[0]->id()), points[0]);
}

}  // namespace
}  // namespace ltlo::map
