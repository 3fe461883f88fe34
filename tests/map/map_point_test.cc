// MapPoint: representative descriptor, normal and scale-invariance distances, fusion.
#include <gtest/gtest.h>

#include "ltlo/features/matching.h"
#include "ltlo/map/map.h"
#include "map_test_util.h"

namespace ltlo::map {
namespace {

TEST(MapPointDescriptor, MedianIndexPicksTheCentralDescriptor) {
  // Distances to z (all zero): 2, 2, 3, 64 -> sorted with itself [0, 2, 2, 3, 64], median 2.
  // For d1: [0, 2, 4, 5, 66] -> 4; d3: [0, 3, 5, 5, 67] -> 5; far: >= 64. So z wins.
  const features::Descriptor z{0, 0, 0, 0};
  const features::Descriptor d1{0b11, 0, 0, 0}, d2{0b1100, 0, 0, 0}, d3{0b1110000, 0, 0, 0};
  const features::Descriptor far{0, 0, 0, ~std::uint64_t{0}};
  EXPECT_EQ(MapPoint::medianDescriptorIndex({d1, far, d2, z, d3}), 3);
  EXPECT_EQ(MapPoint::medianDescriptorIndex({d1, d2}), 0);  // tie at 0 and 4 -> lowest index
  EXPECT_EQ(MapPoint::medianDescriptorIndex({}), -1);
}

TEST(MapPointDescriptor, MapSelectsFromObservingKeyFrames) {
  Map map;
  test::SceneBuilder scene(map, 21);
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  for (int k = 0; k < 5; ++k) kfs.push_back(scene.addKeyFrame());
  const std::shared_ptr<MapPoint> point = scene.share(kfs, 1).front();
  // The observed descriptors are random (pairwise ~128 bits apart); pick by hand as reference.
  std::vector<features::Descriptor> observed;
  for (const auto& kf : kfs) observed.push_back(kf->descriptors()[static_cast<std::size_t>(*point->indexIn(kf->id()))]);
  map.updateDescriptor(*point);
  EXPECT_EQ(point->descriptor(), observed[static_cast<std::size_t>(MapPoint::medianDescriptorIndex(observed))]);
  // Brute-force median check of the selection.
  auto median = [&](const features::Descriptor& d) {
    std::vector<int> dist;
    for (const auto& o : observed) dist.push_back(features::hammingDistance(d, o));
    std::sort(dist.begin(), dist.end());
    return dist[2];
  };
  for (const auto& o : observed) EXPECT_LE(median(point->descriptor()), median(o));
}

TEST(MapPointDescriptor, FollowsEveryChangeOfTheObservationsAndOnlyThem) {
  Map map;
  test::SceneBuilder scene(map, 23);
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  for (int k = 0; k < 6; ++k) kfs.push_back(scene.addKeyFrame());
  const std::shared_ptr<MapPoint> point = scene.share(kfs, 1).front();
  // The median over the observers that are still linked, recomputed from scratch.
  auto expected = [&](const std::vector<std::shared_ptr<KeyFrame>>& observers) {
    std::vector<features::Descriptor> observed;
    for (const auto& kf : observers) {
      observed.push_back(kf->descriptors()[static_cast<std::size_t>(*point->indexIn(kf->id()))]);
    }
    return observed[static_cast<std::size_t>(MapPoint::medianDescriptorIndex(observed))];
  };
  map.updateDescriptor(*point);
  ASSERT_TRUE(point->descriptorCurrent());
  EXPECT_EQ(point->descriptor(), expected(kfs));
  // Erasing the chosen observer's link must move the descriptor to the median of the rest.
  std::vector<std::shared_ptr<KeyFrame>> rest;
  std::shared_ptr<KeyFrame> chosen;
  for (const auto& kf : kfs) {
    const auto index = static_cast<std::size_t>(*point->indexIn(kf->id()));
    if (!chosen && kf->descriptors()[index] == point->descriptor()) {
      chosen = kf;
    } else {
      rest.push_back(kf);
    }
  }
  ASSERT_TRUE(chosen != nullptr);
  const features::Descriptor chosen_descriptor = point->descriptor();
  map.eraseObservation(*chosen, *point->indexIn(chosen->id()));
  EXPECT_FALSE(point->descriptorCurrent());
  map.updateDescriptor(*point);
  EXPECT_EQ(point->descriptor(), expected(rest));
  EXPECT_NE(point->descriptor(), chosen_descriptor);  // random descriptors: ~128 bits apart
  // A descriptor set from outside (a loaded atlas, a new point) is recomputed on the next update.
  point->setDescriptor(features::Descriptor{1, 2, 3, 4});
  EXPECT_FALSE(point->descriptorCurrent());
  map.updateDescriptor(*point);
  EXPECT_EQ(point->descriptor(), expected(rest));
  // Culling an observer (the chosen one unless it is the map's origin) changes them too.
  auto culled = std::find_if(rest.begin() + 1, rest.end(), [&](const std::shared_ptr<KeyFrame>& kf) {
    return kf->descriptors()[static_cast<std::size_t>(*point->indexIn(kf->id()))] == point->descriptor();
  });
  if (culled == rest.end()) culled = rest.begin() + 1;
  ASSERT_NE((*culled)->id(), kfs.front()->id());
  ASSERT_TRUE(map.eraseKeyFrame((*culled)->id()));
  rest.erase(culled);
  ASSERT_EQ(point->numObservations(), static_cast<int>(rest.size()));
  EXPECT_FALSE(point->descriptorCurrent());
  map.updateDescriptor(*point);
  EXPECT_EQ(point->descriptor(), expected(rest));
}

TEST(MapPointGeometry, NormalAndDistancesFromObservations) {
  Map map;
  test::SceneBuilder scene(map, 22);
  // Two cameras 1 m apart on x looking along z (T_b_c = identity); point 2 m ahead of the first.
  const auto a = scene.addKeyFrame(SE3());
  const auto b = scene.addKeyFrame(SE3(Quat::Identity(), Vec3(1.0, 0.0, 0.0)));
  const std::shared_ptr<MapPoint> point = scene.share({a, b}, 1).front();
  point->setPosition(Vec3(0.0, 0.0, 2.0));
  ASSERT_EQ(point->referenceKeyFrame(), a->id());
  map.updateNormalAndDistances(*point);
  const Vec3 expected_normal = (Vec3(0, 0, 1) + Vec3(-1, 0, 2).normalized()).normalized();
  EXPECT_LT((point->normal_w() - expected_normal).norm(), 1e-12);
  const int octave = a->keypoints()[static_cast<std::size_t>(*point->indexIn(a->id()))].octave;
  const double max_expected = 2.0 * test::scaleFactors()[static_cast<std::size_t>(octave)];
  EXPECT_NEAR(point->maxDistance_m(), max_expected, 1e-6);
  EXPECT_NEAR(point->minDistance_m(), max_expected / 1.728, 1e-6);
  // Seen from max_distance it is a level-0 feature; from max / 1.2^2, a level-2 one.
  EXPECT_EQ(point->predictScale(max_expected, test::scaleFactors()), 0);
  EXPECT_EQ(point->predictScale(max_expected / 1.44 * 1.0001, test::scaleFactors()), 2);
  EXPECT_EQ(point->predictScale(0.01, test::scaleFactors()), 3);  // clamped
}

// The observation list stays sorted by keyframe id, one entry per keyframe, however it is built.
TEST(MapPointObservations, SortedByKeyFrameWhateverTheOrderOfLinksAndErasures) {
  Map map;
  test::SceneBuilder scene(map, 24);
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  for (int k = 0; k < 6; ++k) kfs.push_back(scene.addKeyFrame());
  const std::shared_ptr<MapPoint> point = map.createMapPoint(Vec3(0.1, 0.2, 2.0), kfs[3]->id());
  for (const int k : {3, 0, 5, 1, 4}) ASSERT_TRUE(map.addObservation(*kfs[static_cast<std::size_t>(k)], 7 + k, *point));
  EXPECT_FALSE(map.addObservation(*kfs[0], 9, *point));  // kf0 sees it at keypoint 7 already
  map.eraseObservation(*kfs[5], 12);
  map.eraseObservation(*kfs[1], 8);
  ASSERT_TRUE(map.addObservation(*kfs[2], 9, *point));
  const Observations expected = {{kfs[0]->id(), 7}, {kfs[2]->id(), 9}, {kfs[3]->id(), 10}, {kfs[4]->id(), 11}};
  EXPECT_EQ(point->observations(), expected);
  Observations reused(17, {KeyFrameId(), -1});
  point->observationsInto(&reused);
  EXPECT_EQ(reused, expected);
  EXPECT_EQ(point->indexIn(kfs[4]->id()), std::optional<int>(11));
  EXPECT_EQ(point->indexIn(kfs[1]->id()), std::nullopt);
  EXPECT_EQ(point->numObservations(), 4);
  EXPECT_EQ(point->referenceKeyFrame(), kfs[3]->id());
}

TEST(MapPointFusion, ReplaceMovesObservationsAndMarksTheOldPoint) {
  Map map;
  test::SceneBuilder scene(map, 23);
  const auto a = scene.addKeyFrame(), b = scene.addKeyFrame(), c = scene.addKeyFrame();
  const std::shared_ptr<MapPoint> kept = scene.share({a, b}, 1).front();
  const std::shared_ptr<MapPoint> duplicate = scene.share({b, c}, 1).front();
  const int index_in_c = *duplicate->indexIn(c->id());
  ASSERT_TRUE(map.replaceMapPoint(duplicate->id(), kept->id()));
  EXPECT_TRUE(duplicate->isBad());
  EXPECT_EQ(duplicate->replacedBy(), kept->id());
  EXPECT_EQ(map.mapPoint(duplicate->id()), nullptr);
  // c's keypoint now points at the kept point; b already had it at another keypoint.
  EXPECT_EQ(c->mapPoint(index_in_c), kept->id());
  EXPECT_EQ(kept->numObservations(), 3);
  EXPECT_EQ(b->numObservations(), 1);
  EXPECT_EQ(kept->numVisible(), 2);
  EXPECT_FALSE(map.replaceMapPoint(duplicate->id(), kept->id()));
}

TEST(MapPointLookup, ManyIdsUnderOneLockMatchOneByOne) {
  Map map;
  test::SceneBuilder scene(map, 29);
  const auto a = scene.addKeyFrame(), b = scene.addKeyFrame();
  const std::vector<std::shared_ptr<MapPoint>> points = scene.share({a, b}, 4);
  ASSERT_TRUE(map.eraseMapPoint(points[1]->id()));
  // A live point, an erased one, an invalid id, one never made, and a live one again.
  const std::vector<MapPointId> ids = {points[0]->id(), points[1]->id(), MapPointId(), MapPointId(987654),
                                       points[3]->id()};
  std::vector<std::shared_ptr<MapPoint>> found(9, points[2]);  // stale content is overwritten
  map.mapPointsInto(ids, &found);
  ASSERT_EQ(found.size(), ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i) EXPECT_EQ(found[i], map.mapPoint(ids[i])) << "id " << i;
  EXPECT_EQ(found[0], points[0]);
  EXPECT_EQ(found[1], nullptr);
  EXPECT_EQ(found[2], nullptr);
  EXPECT_EQ(found[3], nullptr);
  EXPECT_EQ(found[4], points[3]);
}

}  // namespace
}  // namespace ltlo::map
