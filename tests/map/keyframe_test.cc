// KeyFrame and Map: ownership on culling, covisibility weights and order, spanning-tree repair,
// the IMU chain across a culled keyframe, the essential graph.
#include <gtest/gtest.h>

#include "ltlo/map/essential_graph.h"
#include "ltlo/map/map.h"
#include "map_test_util.h"

namespace ltlo::map {
namespace {

using Covisibles = std::vector<std::pair<KeyFrameId, int>>;

TEST(KeyFrameOwnership, CulledKeyFramesFollowTheCorrectionsOfTheKeyFramesThatRemain) {
  Map map;
  test::SceneBuilder scene(map, 3);
  const SE3 T_w_a(so3ExpQuat(Vec3(0.0, 0.1, 0.0)), Vec3(0.0, 0.0, 0.0));
  const SE3 T_w_b(so3ExpQuat(Vec3(0.0, 0.2, 0.05)), Vec3(0.5, 0.0, 0.1));
  const SE3 T_w_c(so3ExpQuat(Vec3(0.1, 0.3, 0.0)), Vec3(1.0, 0.2, 0.0));
  const std::shared_ptr<KeyFrame> a = scene.addKeyFrame(T_w_a);
  const std::shared_ptr<KeyFrame> b = scene.addKeyFrame(T_w_b);
  const std::shared_ptr<KeyFrame> c = scene.addKeyFrame(T_w_c);
  scene.share({a, b, c}, 30);
  scene.share({b, c}, 20);  // c's best covisible (its parent) is b
  for (const auto& kf : {a, b, c}) map.updateConnections(*kf);
  ASSERT_EQ(c->parent(), b->id());
  ASSERT_TRUE(map.eraseKeyFrame(c->id()));
  ASSERT_TRUE(map.eraseKeyFrame(b->id()));
  ASSERT_EQ(c->culledParent(), b);
  ASSERT_EQ(b->culledParent(), a);
  EXPECT_LT((latestPose_T_w_b(*c).log() - T_w_c.log()).norm(), 1e-12);
  // A correction of the live keyframe moves both culled ones rigidly with it.
  const SE3 correction(so3ExpQuat(Vec3(0.0, 0.0, 0.3)), Vec3(0.2, -0.1, 0.05));
  a->setPose_T_w_b(correction * T_w_a);
  EXPECT_LT((latestPose_T_w_b(*b).log() - (correction * T_w_b).log()).norm(), 1e-12);
  EXPECT_LT((latestPose_T_w_b(*c).log() - (correction * T_w_c).log()).norm(), 1e-12);
  EXPECT_LT((latestPose_T_w_b(*a).log() - (correction * T_w_a).log()).norm(), 1e-12);
}

TEST(KeyFrameOwnership, CulledKeyFrameIsBadAndGoneButHolderKeepsItValid) {
  Map map;
  test::SceneBuilder scene(map, 1);
  const std::shared_ptr<KeyFrame> a = scene.addKeyFrame();
  std::shared_ptr<KeyFrame> b = scene.addKeyFrame();
  const std::vector<std::shared_ptr<MapPoint>> shared = scene.share({a, b}, 20);
  const std::vector<std::shared_ptr<MapPoint>> only_b = scene.share({b}, 5);
  map.updateConnections(*a);
  map.updateConnections(*b);
  ASSERT_EQ(map.numMapPoints(), 25u);

  const KeyFrameId b_id = b->id();
  std::weak_ptr<KeyFrame> watcher = b;
  ASSERT_TRUE(map.eraseKeyFrame(b_id));
  EXPECT_EQ(map.keyFrame(b_id), nullptr);
  EXPECT_EQ(map.numKeyFrames(), 1u);
  // The holder still reads a valid, bad keyframe with its image data intact.
  EXPECT_TRUE(b->isBad());
  EXPECT_EQ(b->numKeypoints(), 200);
  EXPECT_FALSE(map.eraseKeyFrame(b_id));
  // Its observations are gone from the points; points it alone observed are culled with it.
  for (const std::shared_ptr<MapPoint>& p : shared) {
    EXPECT_EQ(p->numObservations(), 1);
    EXPECT_FALSE(p->indexIn(b_id).has_value());
  }
  for (const std::shared_ptr<MapPoint>& p : only_b) EXPECT_TRUE(p->isBad());
  EXPECT_EQ(map.numMapPoints(), 20u);
  EXPECT_EQ(a->weight(b_id), 0);
  EXPECT_TRUE(a->covisibles().empty());
  // A bad keyframe takes no new links.
  EXPECT_FALSE(map.addObservation(*b, 150, *shared.front()));
  b.reset();
  EXPECT_TRUE(watcher.expired());  // the last holder freed it
}

TEST(KeyFrameOwnership, AStandInOfACulledKeyFrameFollowsTheSameChainWithoutItsImageData) {
  Map map;
  test::SceneBuilder scene(map, 3);
  const SE3 T_w_a(so3ExpQuat(Vec3(0.0, 0.1, 0.0)), Vec3(0.0, 0.0, 0.0));
  const SE3 T_w_b(so3ExpQuat(Vec3(0.0, 0.2, 0.05)), Vec3(0.5, 0.0, 0.1));
  const SE3 T_w_c(so3ExpQuat(Vec3(0.1, 0.3, 0.0)), Vec3(1.0, 0.2, 0.0));
  const std::shared_ptr<KeyFrame> a = scene.addKeyFrame(T_w_a);
  std::shared_ptr<KeyFrame> b = scene.addKeyFrame(T_w_b);
  std::shared_ptr<KeyFrame> c = scene.addKeyFrame(T_w_c);
  scene.share({a, b, c}, 30);
  scene.share({b, c}, 20);
  for (const auto& kf : {a, b, c}) map.updateConnections(*kf);
  ASSERT_TRUE(map.eraseKeyFrame(c->id()));
  const std::shared_ptr<KeyFrame> c_stand_in = culledStandIn(*c);
  // The same keyframe to its holders: id, map, time, camera, state, chain.
  EXPECT_EQ(c_stand_in->id(), c->id());
  EXPECT_EQ(c_stand_in->mapId(), c->mapId());
  EXPECT_EQ(c_stand_in->t_s(), c->t_s());
  EXPECT_EQ(c_stand_in->camera().fx(), c->camera().fx());
  EXPECT_EQ(c_stand_in->T_b_c().matrix(), c->T_b_c().matrix());
  EXPECT_EQ(c_stand_in->T_w_b().matrix(), c->T_w_b().matrix());
  EXPECT_EQ(c_stand_in->v_w_b(), c->v_w_b());
  EXPECT_TRUE(c_stand_in->isBad());
  EXPECT_EQ(c_stand_in->culledParent(), b);
  EXPECT_EQ(c_stand_in->T_parent_this().matrix(), c->T_parent_this().matrix());
  // Without the image data.
  EXPECT_EQ(c->numKeypoints(), 200);
  EXPECT_EQ(c_stand_in->numKeypoints(), 0);
  // Its parent culled in turn: the stand-in is pointed at the parent's stand-in, and the whole
  // keyframes are freed once their holders let go.
  ASSERT_TRUE(map.eraseKeyFrame(b->id()));
  const std::shared_ptr<KeyFrame> b_stand_in = culledStandIn(*b);
  EXPECT_EQ(b_stand_in->culledParent(), a);
  c_stand_in->replaceCulledParent(b_stand_in);
  EXPECT_EQ(latestPose_T_w_b(*c_stand_in).matrix(), latestPose_T_w_b(*c).matrix());
  const std::weak_ptr<KeyFrame> b_whole = b, c_whole = c;
  b.reset();
  c.reset();
  EXPECT_TRUE(b_whole.expired());
  EXPECT_TRUE(c_whole.expired());
  // A correction of the live keyframe moves the stand-ins rigidly with it, as it moved the culled ones.
  const SE3 correction(so3ExpQuat(Vec3(0.0, 0.0, 0.3)), Vec3(0.2, -0.1, 0.05));
  a->setPose_T_w_b(correction * T_w_a);
  EXPECT_LT((latestPose_T_w_b(*b_stand_in).log() - (correction * T_w_b).log()).norm(), 1e-12);
  EXPECT_LT((latestPose_T_w_b(*c_stand_in).log() - (correction * T_w_c).log()).norm(), 1e-12);
}

TEST(KeyFrameOwnership, OriginKeyFrameIsNeverCulled) {
  Map map;
  test::SceneBuilder scene(map, 2);
  const std::shared_ptr<KeyFrame> origin = scene.addKeyFrame();
  EXPECT_EQ(map.originKeyFrames(), std::vector<KeyFrameId>{origin->id()});
  EXPECT_FALSE(map.eraseKeyFrame(origin->id()));
  EXPECT_FALSE(origin->isBad());
}

TEST(KeyFrameOwnership, MovingTheGaugeFreesTheOldOriginAndRootsTheTreeAtTheNewOne) {
  // Tracking.StartRecoveryGauge: a start relocalised on b makes b the gauge; a (the first keyframe)
  // can then leave the map, and b, its child, becomes a root.
  Map map;
  test::SceneBuilder scene(map, 3);
  const auto a = scene.addKeyFrame(), b = scene.addKeyFrame(), c = scene.addKeyFrame();
  scene.share({a, b}, 40);
  scene.share({b, c}, 40);
  for (const auto& kf : {a, b, c}) map.updateConnections(*kf);
  ASSERT_EQ(b->parent(), a->id());
  EXPECT_EQ(map.moveGaugeTo(b->id()), a->id());
  EXPECT_EQ(map.gaugeKeyFrame(), b->id());
  EXPECT_EQ(map.originKeyFrames(), std::vector<KeyFrameId>{b->id()});
  EXPECT_EQ(map.moveGaugeTo(b->id()), b->id());  // already the gauge: nothing changes
  EXPECT_FALSE(map.eraseKeyFrame(b->id()));
  ASSERT_TRUE(map.eraseKeyFrame(a->id(), Map::ImuLink::kCut));
  EXPECT_FALSE(b->parent().valid());
  EXPECT_EQ(c->parent(), b->id());
  EXPECT_EQ(map.numKeyFrames(), 2u);
}

TEST(Covisibility, WeightsCountSharedPointsAndOrderBestFirst) {
  Map map;
  test::SceneBuilder scene(map, 3);
  const auto a = scene.addKeyFrame(), b = scene.addKeyFrame(), c = scene.addKeyFrame(), d = scene.addKeyFrame();
  scene.share({a, b}, 40);
  scene.share({a, c}, 20);
  scene.share({b, c}, 30);
  scene.share({a, d}, 5);     // below kMinCovisibilityWeight: only kept as d's single strongest edge
  scene.share({a, b, c}, 2);  // counted on all three pairs
  for (const auto& kf : {a, b, c, d}) map.updateConnections(*kf);

  EXPECT_EQ(a->covisibles(), (Covisibles{{b->id(), 42}, {c->id(), 22}, {d->id(), 5}}));
  EXPECT_EQ(b->covisibles(), (Covisibles{{a->id(), 42}, {c->id(), 32}}));
  EXPECT_EQ(c->covisibles(), (Covisibles{{b->id(), 32}, {a->id(), 22}}));
  EXPECT_EQ(d->covisibles(), (Covisibles{{a->id(), 5}}));
  EXPECT_EQ(a->bestCovisibles(2), (std::vector<KeyFrameId>{b->id(), c->id()}));
  EXPECT_EQ(a->covisiblesWithWeightAtLeast(22), (std::vector<KeyFrameId>{b->id(), c->id()}));
  EXPECT_EQ(c->weight(a->id()), 22);
  EXPECT_EQ(c->weight(d->id()), 0);

  // Spanning tree: the first keyframe is the root, each later one hangs off its best covisible.
  EXPECT_FALSE(a->parent().valid());
  EXPECT_EQ(b->parent(), a->id());
  EXPECT_EQ(c->parent(), b->id());
  EXPECT_EQ(d->parent(), a->id());
  EXPECT_EQ(a->children(), (std::vector<KeyFrameId>{b->id(), d->id()}));

  // Rebuilding a's edges drops the weak edge to d (a's view) but d keeps its fallback edge.
  map.updateConnections(*a);
  EXPECT_EQ(a->covisibles(), (Covisibles{{b->id(), 42}, {c->id(), 22}}));
  EXPECT_EQ(d->weight(a->id()), 5);

  // Ties break by id.
  Map tie_map;
  test::SceneBuilder tie_scene(tie_map, 4);
  const auto t0 = tie_scene.addKeyFrame(), t1 = tie_scene.addKeyFrame(), t2 = tie_scene.addKeyFrame();
  tie_scene.share({t0, t2}, 16);
  tie_scene.share({t0, t1}, 16);
  tie_map.updateConnections(*t0);
  EXPECT_EQ(t0->covisibles(), (Covisibles{{t1->id(), 16}, {t2->id(), 16}}));
}

TEST(SpanningTree, ErasingAKeyFrameReattachesChildrenByCovisibility) {
  // A <- B <- {C, E}; C also sees A (20 points), E sees only B and C. Culling B must hang C on A
  // (the only covisible candidate at first) and then E on C (re-parented siblings become candidates).
  Map map;
  test::SceneBuilder scene(map, 5);
  const auto a = scene.addKeyFrame();
  const auto b = scene.addKeyFrame();
  scene.share({a, b}, 40);
  map.updateConnections(*b);
  const auto c = scene.addKeyFrame();
  scene.share({b, c}, 30);
  scene.share({a, c}, 20);
  map.updateConnections(*c);
  const auto e = scene.addKeyFrame();
  scene.share({b, e}, 60);
  scene.share({c, e}, 50);
  map.updateConnections(*e);
  const auto f = scene.addKeyFrame();  // hangs off E, untouched by the repair
  scene.share({e, f}, 25);
  map.updateConnections(*f);
  ASSERT_EQ(b->parent(), a->id());
  ASSERT_EQ(c->parent(), b->id());
  ASSERT_EQ(e->parent(), b->id());
  ASSERT_EQ(f->parent(), e->id());

  ASSERT_TRUE(map.eraseKeyFrame(b->id()));
  EXPECT_EQ(c->parent(), a->id());
  EXPECT_EQ(e->parent(), c->id());
  EXPECT_EQ(f->parent(), e->id());
  EXPECT_EQ(a->children(), std::vector<KeyFrameId>{c->id()});
  EXPECT_EQ(c->children(), std::vector<KeyFrameId>{e->id()});
  EXPECT_EQ(e->weight(b->id()), 0);
  EXPECT_EQ(c->covisibles(), (Covisibles{{e->id(), 50}, {a->id(), 20}}));

  // A child with no covisibility to any candidate falls back to the culled keyframe's parent.
  const auto g = scene.addKeyFrame();
  scene.share({e, g}, 30);
  map.updateConnections(*g);
  ASSERT_EQ(g->parent(), e->id());
  const auto h = scene.addKeyFrame();  // child of g, shares nothing with e
  scene.share({g, h}, 30);
  map.updateConnections(*h);
  ASSERT_EQ(h->parent(), g->id());
  ASSERT_TRUE(map.eraseKeyFrame(g->id()));
  EXPECT_EQ(h->parent(), e->id());
  EXPECT_EQ(e->children(), (std::vector<KeyFrameId>{f->id(), h->id()}));
}

TEST(ImuChain, CullingBridgesThePreintegration) {
  Map map;
  test::SceneBuilder scene(map, 6);
  const imu::ImuNoise noise;
  auto interval = [&](double w_z, double a_x) {
    imu::Preintegrated pim(imu::ImuBias{}, noise);
    for (int k = 0; k < 20; ++k) pim.integrateStep(Vec3(0.0, 0.0, w_z), Vec3(a_x, 0.0, 9.81), 0.005);
    return pim;
  };
  const auto k0 = scene.addKeyFrame(), k1 = scene.addKeyFrame(), k2 = scene.addKeyFrame();
  k0->setNextKeyFrame(k1->id());
  k1->setPreviousKeyFrame(k0->id());
  k1->setNextKeyFrame(k2->id());
  k2->setPreviousKeyFrame(k1->id());
  const imu::Preintegrated first = interval(0.3, 0.5), second = interval(-0.2, 1.0);
  k1->setImuFromPrevious(first);
  k2->setImuFromPrevious(second);
  ASSERT_TRUE(map.eraseKeyFrame(k1->id()));
  EXPECT_EQ(k0->nextKeyFrame(), k2->id());
  EXPECT_EQ(k2->previousKeyFrame(), k0->id());
  const std::optional<imu::Preintegrated> bridged = k2->imuFromPrevious();
  ASSERT_TRUE(bridged.has_value());
  const imu::Preintegrated expected = imu::Preintegrated::merged(first, second);
  EXPECT_NEAR(bridged->dt_s(), 0.2, 1e-12);
  EXPECT_LT((bridged->deltaP() - expected.deltaP()).norm(), 1e-15);
  EXPECT_LT((bridged->deltaR() - expected.deltaR()).norm(), 1e-15);
}

TEST(EssentialGraph, TreeLoopAndStrongCovisibilityEdgesOnce) {
  Map map;
  test::SceneBuilder scene(map, 7);
  const auto a = scene.addKeyFrame(SE3(), 400), b = scene.addKeyFrame(SE3(), 400), c = scene.addKeyFrame(SE3(), 400),
             d = scene.addKeyFrame(SE3(), 400);
  scene.share({a, b}, 120);
  map.updateConnections(*b);
  scene.share({b, c}, 150);
  scene.share({a, c}, 110);  // strong but not a tree edge
  map.updateConnections(*c);
  scene.share({c, d}, 40);
  scene.share({a, d}, 99);  // below 100: not essential
  map.updateConnections(*d);
  a->addLoopEdge(d->id());
  d->addLoopEdge(a->id());
  ASSERT_EQ(d->parent(), a->id());  // 99 > 40

  // d's parent is a, so the a-d pair is a tree edge and the loop edge adds nothing.
  const std::vector<EssentialEdge> edges = essentialGraphEdges(map);
  ASSERT_EQ(edges.size(), 4u);
  EXPECT_EQ(edges[0].kind, EdgeKind::kSpanningTree);
  EXPECT_EQ(edges[0].from, b->id());
  EXPECT_EQ(edges[0].to, a->id());
  EXPECT_EQ(edges[0].weight, 120);
  EXPECT_EQ(edges[1].from, c->id());
  EXPECT_EQ(edges[1].to, b->id());
  EXPECT_EQ(edges[2].from, d->id());
  EXPECT_EQ(edges[2].to, a->id());
  EXPECT_EQ(edges[3].kind, EdgeKind::kCovisibility);
  EXPECT_EQ(edges[3].from, a->id());
  EXPECT_EQ(edges[3].to, c->id());
  EXPECT_EQ(edges[3].weight, 110);

  // A loop edge between keyframes that are not tree neighbours appears once, as a loop.
  b->addLoopEdge(d->id());
  const std::vector<EssentialEdge> with_loop = essentialGraphEdges(map);
  ASSERT_EQ(with_loop.size(), 5u);
  EXPECT_EQ(with_loop[4].kind, EdgeKind::kLoop);
  EXPECT_EQ(with_loop[4].from, b->id());
  EXPECT_EQ(with_loop[4].to, d->id());
  EXPECT_EQ(essentialGraphEdges(map, 151).size(), 4u);  // no covisibility edge that strong

  // With the IMU: the chain a -> b -> c -> d adds c-d (not yet linked; a-b and b-c are tree edges)
  // as an inertial edge, ordered earlier -> later.
  b->setPreviousKeyFrame(a->id());
  c->setPreviousKeyFrame(b->id());
  d->setPreviousKeyFrame(c->id());
  EXPECT_EQ(essentialGraphEdges(map).size(), 5u);  // without it, unchanged
  const std::vector<EssentialEdge> inertial = essentialGraphEdges(map, kEssentialCovisibilityWeight, true);
  ASSERT_EQ(inertial.size(), 6u);
  EXPECT_EQ(inertial[5].kind, EdgeKind::kInertial);
  EXPECT_EQ(inertial[5].from, c->id());
  EXPECT_EQ(inertial[5].to, d->id());
  EXPECT_EQ(inertial[5].weight, 40);
}

}  // namespace
}  // namespace ltlo::map
