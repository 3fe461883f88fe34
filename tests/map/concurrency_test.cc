// Several threads on one Atlas through the public API: a mapper inserting keyframes and points, a
// culler erasing keyframes, fusing and erasing points, a loop thread moving poses, a lost-tracking
// thread growing a second map and merging it back, and readers taking snapshots and querying the
// database. Synchronised with queues only (no sleeps); run under TSan.
#include <atomic>
#include <thread>

#include <gtest/gtest.h>

#include "bow/vocabulary.h"
#include "ltlo/core/blocking_queue.h"
#include "ltlo/map/atlas.h"
#include "map_test_util.h"

namespace ltlo::map {
namespace {

constexpr int kNumFrames = 60;

TEST(MapConcurrency, InsertCullReadAndCorrectFromSeveralThreads) {
  std::mt19937 rng(41);
  // Frames are generated up front (Frame is single-threaded); the vocabulary is tiny.
  std::vector<Frame> frames;
  for (int k = 0; k < kNumFrames; ++k) {
    frames.push_back(test::randomFrame(rng, 0.1 * k, SE3(Quat::Identity(), Vec3(0.05 * k, 0.0, 0.0)), 120));
  }
  const bow::Vocabulary vocabulary = bow::Vocabulary::train({frames[0].descriptors(), frames[1].descriptors()},
                                                            bow::TrainOptions{4, 3, 5, 1, 1, 0, {}});
  for (Frame& f : frames) f.computeBow(vocabulary);

  Atlas atlas(vocabulary.numWords());
  Map& map = atlas.activeMap();
  BlockingQueue<std::size_t> to_mapper(4);
  BlockingQueue<std::shared_ptr<KeyFrame>> to_culler(4);
  BlockingQueue<std::shared_ptr<KeyFrame>> to_loop(4);
  std::atomic<int> inserted{0}, culled{0}, fused{0}, reads{0};
  Vec3 merged_point_p_w = Vec3::Zero();  // written by `lost`, read after join

  std::thread mapper([&] {  // local mapping: keyframes, points shared with the last 3 keyframes
    std::vector<std::shared_ptr<KeyFrame>> recent;
    std::mt19937 mapper_rng(42);
    while (std::optional<std::size_t> index = to_mapper.pop()) {
      const std::shared_ptr<KeyFrame> kf = map.createKeyFrame(frames[*index]);
      atlas.keyFrameDatabase().add(kf);
      int next_keypoint = 0;
      for (const std::shared_ptr<KeyFrame>& other : recent) {
        for (int n = 0; n < 20; ++n) {
          const std::shared_ptr<MapPoint> p = map.createMapPoint(Vec3(0.05 * *index, 0.1 * n, 3.0), kf->id());
          map.addObservation(*kf, next_keypoint++, *p);
          // other may have been culled meanwhile: the link is refused on both ends then.
          map.addObservation(*other, static_cast<int>(mapper_rng() % 120), *p);
          map.updateDescriptor(*p);
          map.updateNormalAndDistances(*p);
        }
      }
      map.updateConnections(*kf);
      recent.push_back(kf);
      if (recent.size() > 3) recent.erase(recent.begin());
      ++inserted;
      to_culler.push(kf);
      to_loop.push(kf);
    }
    to_culler.close();
    to_loop.close();
  });

  std::thread culler([&] {  // culling: every third keyframe, some points erased or fused
    int count = 0;
    MapPointId last_point;
    while (std::optional<std::shared_ptr<KeyFrame>> kf = to_culler.pop()) {
      if (++count % 3 == 0 && map.eraseKeyFrame((*kf)->id())) {
        atlas.keyFrameDatabase().erase((*kf)->id());
        ++culled;
      }
      const std::vector<MapPointId> points = (*kf)->mapPoints();
      for (MapPointId p : points) {
        if (!p.valid()) continue;
        if (p.value % 7 == 0) map.eraseMapPoint(p);
        if (p.value % 11 == 0 && last_point.valid() && map.replaceMapPoint(p, last_point)) ++fused;
        last_point = p;
      }
    }
  });

  std::thread loop([&] {  // loop correction: shift every keyframe, then bump the version
    while (std::optional<std::shared_ptr<KeyFrame>> kf = to_loop.pop()) {
      if ((*kf)->id().value % 10 != 9) continue;
      for (const std::shared_ptr<KeyFrame>& k : map.keyFrames()) {
        k->setPose_T_w_b(SE3(Quat::Identity(), Vec3(0.0, 0.0, 0.01)) * k->T_w_b());
      }
      for (const std::shared_ptr<MapPoint>& p : map.mapPoints()) p->setPosition(p->p_w() + Vec3(0.0, 0.0, 0.01));
      map.bumpVersion();
      atlas.keyFrameDatabase().detectLoopCandidates(**kf, 0.8, {});
    }
  });

  std::thread lost([&] {  // tracking lost once: a second map grows, then merges back into the first
    Map& second = atlas.createNewMap();
    std::vector<std::shared_ptr<KeyFrame>> kfs;
    for (std::size_t k = 0; k < 3; ++k) {
      kfs.push_back(second.createKeyFrame(frames[k]));
      atlas.keyFrameDatabase().add(kfs.back());
    }
    const std::vector<std::shared_ptr<MapPoint>> points = {second.createMapPoint(Vec3(1.0, 2.0, 3.0), kfs[0]->id())};
    for (int k = 0; k < 3; ++k) second.addObservation(*kfs[static_cast<std::size_t>(k)], k, *points[0]);
    for (const auto& kf : kfs) second.updateConnections(*kf);
    atlas.mergeMaps(second.id(), map.id(), SE3(Quat::Identity(), Vec3(0.5, 0.0, 0.0)));
    merged_point_p_w = points[0]->p_w();
  });

  // tracking: snapshots and relocalisation queries; a keyframe's points one by one or all under one
  // lock (Map::mapPointsInto, as tracking's searches do)
  auto reader = [&](int iterations, bool batched) {
    std::vector<std::shared_ptr<MapPoint>> looked_up;
    for (int it = 0; it < iterations; ++it) {
      for (const std::shared_ptr<KeyFrame>& kf : map.keyFrames()) {
        const SE3 T_w_c = kf->T_w_c();
        (void)T_w_c;
        for (const auto& [other, w] : kf->covisibles()) (void)map.keyFrame(other);
        const std::vector<MapPointId> ids = kf->mapPoints();
        if (batched) {
          map.mapPointsInto(ids, &looked_up);
        } else {
          looked_up.clear();
          for (MapPointId id : ids) looked_up.push_back(map.mapPoint(id));
        }
        for (const std::shared_ptr<MapPoint>& p : looked_up) {
          if (p) {
            (void)p->p_w();
            (void)p->descriptor();
            p->increaseVisible();
          }
        }
        (void)kf->parent();
      }
      (void)map.version();
      (void)atlas.keyFrameDatabase().detectRelocalisationCandidates(frames[static_cast<std::size_t>(it % kNumFrames)],
                                                                    atlas.activeMapId(), {});
      ++reads;
    }
  };
  std::thread reader_a(reader, 40, false), reader_b(reader, 40, true);

  for (std::size_t k = 0; k < frames.size(); ++k) to_mapper.push(k);
  to_mapper.close();
  reader_a.join();
  reader_b.join();
  lost.join();
  mapper.join();
  culler.join();
  loop.join();

  EXPECT_EQ(inserted.load(), kNumFrames);
  EXPECT_EQ(reads.load(), 80);
  EXPECT_GT(culled.load(), 10);
  EXPECT_GT(fused.load(), 0);
  EXPECT_EQ(map.numKeyFrames(), static_cast<std::size_t>(kNumFrames + 3 - culled.load()));
  EXPECT_EQ(atlas.mapIds(), std::vector<MapId>{map.id()});
  EXPECT_EQ(atlas.activeMapId(), map.id());
  // Loop corrections before the merge moved only the first map's points; the merge adds 0.5 m in x.
  EXPECT_NEAR(merged_point_p_w.x(), 1.5, 1e-12);
  EXPECT_EQ(atlas.keyFrameDatabase().size(), map.numKeyFrames());

  // The map is consistent after the dust settles: links on both ends, a spanning tree.
  const std::vector<KeyFrameId> origins = map.originKeyFrames();
  for (const std::shared_ptr<KeyFrame>& kf : map.keyFrames()) {
    EXPECT_FALSE(kf->isBad());
    const std::vector<MapPointId> points = kf->mapPoints();
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!points[i].valid()) continue;
      const std::shared_ptr<MapPoint> p = map.mapPoint(points[i]);
      ASSERT_NE(p, nullptr) << kf->id() << " keypoint " << i << " links to an erased " << points[i];
      EXPECT_EQ(p->indexIn(kf->id()), std::optional<int>(static_cast<int>(i)));
    }
    for (const auto& [other, w] : kf->covisibles())
      EXPECT_NE(map.keyFrame(other), nullptr) << kf->id() << " -> " << other;
    if (std::find(origins.begin(), origins.end(), kf->id()) != origins.end()) continue;
    const std::shared_ptr<KeyFrame> parent = map.keyFrame(kf->parent());
    ASSERT_NE(parent, nullptr) << kf->id() << " has parent " << kf->parent() << ", t = " << kf->t_s() << " s";
    const std::vector<KeyFrameId> siblings = parent->children();
    EXPECT_NE(std::find(siblings.begin(), siblings.end(), kf->id()), siblings.end());
  }
  for (const std::shared_ptr<MapPoint>& p : map.mapPoints()) {
    EXPECT_FALSE(p->isBad());
    for (const auto& [kf_id, index] : p->observations()) {
      const std::shared_ptr<KeyFrame> kf = map.keyFrame(kf_id);
      ASSERT_NE(kf, nullptr) << p->id() << " observed by an erased " << kf_id;
      EXPECT_EQ(kf->mapPoint(index), p->id());
    }
  }
}

}  // namespace
}  // namespace ltlo::map
