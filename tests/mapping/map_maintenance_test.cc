// Map maintenance of local mapping on generated keyframes (no images, fixed seeds): duplicate
// fusion by projection (links, merges, descriptor and static-score gates) and keyframe culling
// (redundancy, origin, the IMU time-span rule); the IMU chain's end at the newest mostly-static view.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "../../src/mapping/imu_initializer.h"
#include "../../src/mapping/map_culling.h"
#include "../../src/mapping/point_fusion.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/map.h"

namespace ltlo::mapping {
namespace {

PinholeCamera qvgaCamera() { return PinholeCamera(262.5, 262.5, 159.5, 119.5, 320, 240); }
std::vector<float> scaleFactors() { return {1.0f, 1.2f, 1.44f, 1.728f}; }
std::vector<float> levelSigma2() { return {1.0f, 1.44f, 2.0736f, 2.985984f}; }

features::Descriptor randomDescriptor(std::mt19937& rng) {
  std::uniform_int_distribution<std::uint64_t> bits;
  return {bits(rng), bits(rng), bits(rng), bits(rng)};
}

/// A frame at T_w_b (camera = body) whose keypoint k sits at the projection of points_w[k] with
/// its exact depth, octave 0 and descriptors[k].
map::Frame frameSeeing(double t_s, const SE3& T_w_b, const std::vector<Vec3>& points_w,
                       const std::vector<features::Descriptor>& descriptors) {
  const PinholeCamera camera = qvgaCamera();
  features::OrbFeatures features;
  std::vector<float> depths;
  for (std::size_t k = 0; k < points_w.size(); ++k) {
    const Vec3 p_c = T_w_b.inverse() * points_w[k];
    const Vec2 uv = camera.project(p_c);
    features::Keypoint kp;
    kp.x_px = static_cast<float>(uv.x());
    kp.y_px = static_cast<float>(uv.y());
    kp.octave = 0;
    features.keypoints.push_back(kp);
    features.descriptors.push_back(descriptors[k]);
    depths.push_back(static_cast<float>(p_c.z()));
  }
  map::Frame frame(t_s, camera, SE3(), std::move(features), std::move(depths), scaleFactors());
  frame.setPose_T_w_b(T_w_b);
  return frame;
}

/// `count` points in front of the identity camera, 2-3 m away, spread over the image.
std::vector<Vec3> pointsAhead(std::mt19937& rng, int count) {
  std::uniform_real_distribution<double> u(20.0, 300.0), v(20.0, 220.0), z(2.0, 3.0);
  const PinholeCamera camera = qvgaCamera();
  std::vector<Vec3> points;
  for (int k = 0; k < count; ++k) points.push_back(camera.backProject(Vec2(u(rng), v(rng)), z(rng)));
  return points;
}

TEST(PointFusion, LinksMergesAndRespectsDescriptorAndStaticScoreGates) {
  std::mt19937 rng(3);
  const std::vector<Vec3> points_w = pointsAhead(rng, 30);
  std::vector<features::Descriptor> descriptors;
  for (int k = 0; k < 30; ++k) descriptors.push_back(randomDescriptor(rng));
  // B's keypoints 20..29 carry unrelated descriptors (no match).
  std::vector<features::Descriptor> descriptors_b = descriptors;
  for (int k = 20; k < 30; ++k) descriptors_b[static_cast<std::size_t>(k)] = randomDescriptor(rng);

  map::Map map;
  const auto a = map.createKeyFrame(frameSeeing(0.0, SE3(), points_w, descriptors));
  const SE3 T_w_b(Quat::Identity(), Vec3(0.08, 0.0, 0.02));
  const auto b = map.createKeyFrame(frameSeeing(0.1, T_w_b, points_w, descriptors_b));
  std::vector<std::shared_ptr<map::MapPoint>> points_a;
  std::vector<std::shared_ptr<map::MapPoint>> duplicates;
  for (int k = 0; k < 30; ++k) {
    auto point = map.createMapPoint(points_w[static_cast<std::size_t>(k)], a->id());
    ASSERT_TRUE(map.addObservation(*a, k, *point));
    map.updateNormalAndDistances(*point);
    map.updateDescriptor(*point);
    points_a.push_back(point);
    if (k >= 10 && k < 20) {  // B already holds a duplicate, 5 mm off
      auto duplicate = map.createMapPoint(points_w[static_cast<std::size_t>(k)] + Vec3(0.005, 0.0, 0.0), b->id());
      ASSERT_TRUE(map.addObservation(*b, k, *duplicate));
      map.updateNormalAndDistances(*duplicate);
      map.updateDescriptor(*duplicate);
      duplicates.push_back(duplicate);
    }
  }
  points_a[5]->setBeta(0.2);  // dynamic: never fused

  FusionOptions options;
  const FusionStats stats = fusePointsInto(map, *b, points_a, options, levelSigma2());
  EXPECT_EQ(stats.linked, 9);
  EXPECT_EQ(stats.replaced, 10);
  for (int k = 0; k < 30; ++k) {
    const std::optional<int> in_b = points_a[static_cast<std::size_t>(k)]->indexIn(b->id());
    if (k < 20 && k != 5) {
      ASSERT_TRUE(in_b.has_value()) << "point " << k;
      EXPECT_EQ(*in_b, k);
    } else {
      EXPECT_FALSE(in_b.has_value()) << "point " << k;
    }
  }
  for (std::size_t n = 0; n < duplicates.size(); ++n) {
    EXPECT_TRUE(duplicates[n]->isBad());
    EXPECT_EQ(duplicates[n]->replacedBy(), points_a[10 + n]->id());
  }
  EXPECT_EQ(map.numMapPoints(), 30u);
}

/// Seven keyframes (kf0 the origin); kf1..kf6 all see the same 40 points at octave 0.
struct RedundantChain {
  explicit RedundantChain(double dt_s) {
    std::mt19937 rng(11);
    const std::vector<Vec3> points_w = pointsAhead(rng, 40);
    std::vector<features::Descriptor> descriptors;
    for (int k = 0; k < 40; ++k) descriptors.push_back(randomDescriptor(rng));
    for (int n = 0; n < 7; ++n) {
      const SE3 T_w_b(Quat::Identity(), Vec3(0.01 * n, 0.0, 0.0));
      keyframes.push_back(map.createKeyFrame(frameSeeing(dt_s * n, T_w_b, points_w, descriptors)));
    }
    for (int k = 0; k < 40; ++k) {
      auto point = map.createMapPoint(points_w[static_cast<std::size_t>(k)], keyframes[1]->id());
      for (int n = 1; n < 7; ++n) map.addObservation(*keyframes[static_cast<std::size_t>(n)], k, *point);
    }
    // kf0 shares a few points with kf1 only (it is connected, and it is the origin).
    for (int k = 0; k < 20; ++k) {
      auto point = map.createMapPoint(points_w[static_cast<std::size_t>(k)], keyframes[0]->id());
      map.addObservation(*keyframes[0], k, *point);
    }
    for (int n = 0; n < 7; ++n) {
      auto& kf = keyframes[static_cast<std::size_t>(n)];
      if (n > 0) {
        kf->setPreviousKeyFrame(keyframes[static_cast<std::size_t>(n - 1)]->id());
        keyframes[static_cast<std::size_t>(n - 1)]->setNextKeyFrame(kf->id());
        imu::Preintegrated pim{imu::ImuBias(), imu::ImuNoise()};
        for (int s = 0; s < 10; ++s) pim.integrateStep(Vec3::Zero(), Vec3(0.0, 0.0, 9.81), dt_s / 10.0);
        kf->setImuFromPrevious(pim);
      }
    }
    for (auto& kf : keyframes) map.updateConnections(*kf);
  }
  map::Map map;
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
};

TEST(KeyFrameCulling, CullsRedundantKeyFramesButNotTheOriginOrTheNewest) {
  RedundantChain scene(0.1);
  KeyFrameCullingOptions options;
  options.use_imu = false;
  const std::vector<map::KeyFrameId> culled = cullRedundantKeyFrames(scene.map, *scene.keyframes[6], options);
  // kf1 (points seen by 5 others) and kf2 (4 others) go; then the map is down to 5 keyframes.
  ASSERT_EQ(culled.size(), 2u);
  EXPECT_EQ(culled[0], scene.keyframes[1]->id());
  EXPECT_EQ(culled[1], scene.keyframes[2]->id());
  EXPECT_TRUE(scene.keyframes[1]->isBad());
  EXPECT_FALSE(scene.keyframes[0]->isBad());
  EXPECT_FALSE(scene.keyframes[6]->isBad());
  EXPECT_EQ(scene.map.numKeyFrames(), 5u);
}

TEST(KeyFrameCulling, WithTheImuKeepsKeyFramesWhoseNeighboursSpanMoreThanHalfASecond) {
  RedundantChain slow(0.3);  // neighbours of a keyframe 0.6 s apart
  KeyFrameCullingOptions options;
  options.use_imu = true;
  EXPECT_TRUE(cullRedundantKeyFrames(slow.map, *slow.keyframes[6], options).empty());

  RedundantChain fast(0.1);
  const std::vector<map::KeyFrameId> culled = cullRedundantKeyFrames(fast.map, *fast.keyframes[6], options);
  ASSERT_EQ(culled.size(), 2u);
  // The IMU chain is bridged: kf3 follows kf0 with the merged 0.3 s preintegration.
  const auto& kf3 = fast.keyframes[3];
  EXPECT_EQ(kf3->previousKeyFrame(), fast.keyframes[0]->id());
  ASSERT_TRUE(kf3->imuFromPrevious().has_value());
  EXPECT_NEAR(kf3->imuFromPrevious()->dt_s(), 0.3, 1e-9);
}

// LocalMapping.CullImuCutAge: keyframes old enough are culled whatever their neighbours' span, and
// the chain is cut there instead of bridged; the younger ones keep the span rule.
TEST(KeyFrameCulling, OldKeyFramesAreCulledWithTheirImuLinkCut) {
  RedundantChain slow(2.0);  // neighbours 4 s apart: never bridged (0.5 s); kf6 at 12 s
  KeyFrameCullingOptions options;
  options.use_imu = true;
  options.cut_imu_min_age_s = 6.0;  // kf1 (next kf2 at 4 s) and kf2 (next kf3 at 6 s) old enough, kf3 not
  int cut_links = 0;
  const std::vector<map::KeyFrameId> culled =
      cullRedundantKeyFrames(slow.map, *slow.keyframes[6], options, &cut_links);
  ASSERT_EQ(culled.size(), 2u);
  EXPECT_EQ(cut_links, 2);
  EXPECT_TRUE(slow.keyframes[1]->isBad());
  EXPECT_TRUE(slow.keyframes[2]->isBad());
  // kf3 follows kf0 in time with no preintegration (a gap); kf4..kf6 keep their 2 s links.
  const auto& kf3 = slow.keyframes[3];
  EXPECT_EQ(kf3->previousKeyFrame(), slow.keyframes[0]->id());
  EXPECT_EQ(slow.keyframes[0]->nextKeyFrame(), kf3->id());
  EXPECT_FALSE(kf3->imuFromPrevious().has_value());
  for (int n = 4; n < 7; ++n) {
    ASSERT_TRUE(slow.keyframes[static_cast<std::size_t>(n)]->imuFromPrevious().has_value());
    EXPECT_NEAR(slow.keyframes[static_cast<std::size_t>(n)]->imuFromPrevious()->dt_s(), 2.0, 1e-9);
  }

  // Younger than the age (8 s): only kf1 (next kf2 at 4 s, 8 s before kf6) may go.
  RedundantChain younger(2.0);
  options.cut_imu_min_age_s = 8.0;
  const std::vector<map::KeyFrameId> culled_young = cullRedundantKeyFrames(younger.map, *younger.keyframes[6], options);
  ASSERT_EQ(culled_young.size(), 1u);
  EXPECT_EQ(culled_young[0], younger.keyframes[1]->id());
  // Off (0): the span rule alone, nothing culled.
  RedundantChain off(2.0);
  options.cut_imu_min_age_s = 0.0;
  EXPECT_TRUE(cullRedundantKeyFrames(off.map, *off.keyframes[6], options).empty());
}

// The redundancy test stops early once its answer is certain; its answer must be the full count's
// at every ratio, including at the boundary (36 of 40 points is exactly 0.9).
TEST(KeyFrameCulling, RedundancyDecisionEqualsTheFullCountAtEveryRatio) {
  std::mt19937 rng(29);
  for (int trial = 0; trial < 12; ++trial) {
    RedundantChain scene(0.1);
    // Points kf1 sees with fewer than 3 others: observations by kf2..kf4 (or kf2..kf5) erased.
    std::vector<int> order(40);
    for (int k = 0; k < 40; ++k) order[static_cast<std::size_t>(k)] = k;
    std::shuffle(order.begin(), order.end(), rng);
    const int lonely = trial < 2 ? 4 + trial : std::uniform_int_distribution<int>(0, 40)(rng);
    for (int j = 0; j < lonely; ++j) {
      const int k = order[static_cast<std::size_t>(j)];
      const int last = std::uniform_int_distribution<int>(4, 5)(rng);
      for (int n = 2; n <= last; ++n) scene.map.eraseObservation(*scene.keyframes[static_cast<std::size_t>(n)], k);
    }
    const map::KeyFrame& kf1 = *scene.keyframes[1];
    int redundant = 0, with_depth = 0;
    for (const map::MapPointId id : kf1.mapPoints()) {
      const std::shared_ptr<map::MapPoint> point = scene.map.mapPoint(id);
      if (!point) continue;
      ++with_depth;
      if (point->numObservations() - 1 >= 3) ++redundant;
    }
    ASSERT_EQ(with_depth, 40);
    EXPECT_EQ(redundant, 40 - lonely);
    for (const double ratio : {0.5, 0.7, 0.875, 0.9, 0.9 + 1e-12, 0.95, 1.0}) {
      EXPECT_EQ(mostlyRedundant(scene.map, kf1, 3, ratio), static_cast<double>(redundant) / with_depth >= ratio)
          << lonely << " lonely points, ratio " << ratio;
    }
  }
}

TEST(RecentPointCulling, ErasesPointsNotConfirmedByLaterKeyFrames) {
  std::mt19937 rng(5);
  const std::vector<Vec3> points_w = pointsAhead(rng, 4);
  std::vector<features::Descriptor> descriptors;
  for (int k = 0; k < 4; ++k) descriptors.push_back(randomDescriptor(rng));
  map::Atlas atlas(16);
  map::Map& map = atlas.activeMap();
  const auto a = map.createKeyFrame(frameSeeing(0.0, SE3(), points_w, descriptors));
  const auto b = map.createKeyFrame(frameSeeing(0.1, SE3(), points_w, descriptors));
  std::vector<std::shared_ptr<map::MapPoint>> points;
  for (int k = 0; k < 4; ++k) {
    points.push_back(map.createMapPoint(points_w[static_cast<std::size_t>(k)], a->id()));
    ASSERT_TRUE(map.addObservation(*a, k, *points.back()));
  }
  points[1]->increaseVisible(10);  // found 1 of 11 times by tracking
  points[2]->setBeta(0.1);         // dynamic
  ASSERT_TRUE(map.addObservation(*b, 3, *points[3]));  // confirmed by a second keyframe

  RecentPointCuller culler{RecentPointCuller::Options()};
  culler.addPointsOf(map, *a, 1);
  EXPECT_EQ(culler.size(), 4u);
  EXPECT_EQ(culler.cull(atlas, 1), 2);  // the badly tracked and the dynamic point at once
  EXPECT_TRUE(points[1]->isBad());
  EXPECT_TRUE(points[2]->isBad());
  EXPECT_EQ(culler.cull(atlas, 2), 0);
  EXPECT_EQ(culler.cull(atlas, 3), 1);  // two keyframes later, seen by one keyframe only
  EXPECT_TRUE(points[0]->isBad());
  EXPECT_FALSE(points[3]->isBad());
  EXPECT_EQ(culler.size(), 1u);
  EXPECT_EQ(culler.cull(atlas, 4), 0);  // mature: no longer checked
  EXPECT_EQ(culler.size(), 0u);
  EXPECT_EQ(map.numMapPoints(), 1u);
}

/// Two depth clusters (static, dynamic) and the no-depth cluster, `static_share` of the pixels
/// with depth in the static one.
map::ClusterSegmentation staticShare(double static_share) {
  map::ClusterSegmentation seg;
  seg.labels = cv::Mat(10, 10, CV_8U, cv::Scalar(2));
  seg.gamma = {1.0, 0.0, 1.0};
  const int static_pixels = static_cast<int>(std::lround(100.0 * static_share));
  seg.pixel_counts = {static_pixels, 100 - static_pixels, 0};
  return seg;
}

TEST(ImuChain, EndsAtTheNewestKeyFrameWithAMostlyStaticView) {
  // A box covers more and more of the view, leaves, and covers it again (ImuInit.MinStaticRatio).
  const std::vector<double> static_share = {1.0, 0.9, 0.6, 0.3, 0.7, 0.2, 0.1};
  std::mt19937 rng(5);
  map::Map map;
  ImuChain chain;
  for (std::size_t k = 0; k < static_share.size(); ++k) {
    map::Frame frame = frameSeeing(0.5 * static_cast<double>(k), SE3(), {}, {});
    frame.setSegmentation(staticShare(static_share[k]), 0.5);
    chain.keyframes.push_back(map.createKeyFrame(frame));
    if (k > 0) chain.pims.push_back(std::make_shared<const imu::Preintegrated>(imu::ImuBias(), imu::ImuNoise()));
  }
  const ImuChain half = endAtStaticView(chain, 0.5);
  ASSERT_EQ(half.keyframes.size(), 5u);  // up to the 0.7 view; the 0.3 inside stays
  EXPECT_EQ(half.keyframes.back(), chain.keyframes[4]);
  EXPECT_EQ(half.pims.size(), 4u);
  EXPECT_EQ(half.pims.back(), chain.pims[3]);
  EXPECT_DOUBLE_EQ(half.span_s(), 2.0);
  EXPECT_EQ(endAtStaticView(chain, 0.0).keyframes.size(), chain.keyframes.size());  // off
  const ImuChain strict = endAtStaticView(chain, 0.95);
  EXPECT_EQ(strict.keyframes.size(), 1u);
  EXPECT_TRUE(strict.pims.empty());
  EXPECT_TRUE(endAtStaticView(chain, 1.01).keyframes.empty());
}

}  // namespace
}  // namespace ltlo::mapping
