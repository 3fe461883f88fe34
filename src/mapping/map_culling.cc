#include "map_culling.h"

#include <algorithm>
#include <optional>
#include <unordered_map>

namespace ltlo::mapping {

void RecentPointCuller::addPointsOf(const map::Map& map, const map::KeyFrame& kf, int sequence) {
  const std::vector<map::MapPointId> ids = kf.mapPoints();
  std::vector<std::shared_ptr<map::MapPoint>> points;
  map.mapPointsInto(ids, &points);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const std::shared_ptr<map::MapPoint>& point = points[i];
    if (point && !point->isBad() && point->referenceKeyFrame() == kf.id()) {
      entries_.push_back({map.id(), ids[i], sequence});
    }
  }
}

void RecentPointCuller::writeState(map::ByteWriter& out) const {
  out.u64(entries_.size());
  for (const Entry& entry : entries_) {
    out.u64(entry.map.value);
    out.u64(entry.point.value);
    out.i32(entry.created_at);
  }
}

void RecentPointCuller::readState(map::ByteReader& in) {
  const std::size_t n = in.count("recent map points", 8 + 8 + 4);
  entries_.clear();
  for (std::size_t k = 0; k < n; ++k) {
    Entry entry;
    entry.map = map::MapId(in.u64("recent point map"));
    entry.point = map::MapPointId(in.u64("recent map point"));
    entry.created_at = in.i32("recent point's keyframe");
    entries_.push_back(entry);
  }
}

int RecentPointCuller::cull(map::Atlas& atlas, int sequence) {
  int culled = 0;
  std::deque<Entry> kept;
  for (const Entry& entry : entries_) {
    map::Map* map = atlas.map(entry.map);
    const std::shared_ptr<map::MapPoint> point = map != nullptr ? map->mapPoint(entry.point) : nullptr;
    if (!point || point->isBad()) continue;  // culled, fused or merged into another map meanwhile
    const int age = sequence - entry.created_at;
    const bool unconfirmed = point->foundRatio() < options_.min_found_ratio ||
                             (age >= options_.min_age && point->numObservations() < options_.min_observations);
    if (unconfirmed || point->beta() < options_.min_point_beta) {
      if (map->eraseMapPoint(entry.point)) ++culled;
      continue;
    }
    if (age < options_.mature_age) kept.push_back(entry);
  }
  entries_.swap(kept);
  return culled;
}

int cullDynamicPoints(map::Map& map, const map::KeyFrame& kf, double min_point_beta) {
  int culled = 0;
  const std::vector<map::MapPointId> ids = kf.mapPoints();
  std::vector<std::shared_ptr<map::MapPoint>> points;
  map.mapPointsInto(ids, &points);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const std::shared_ptr<map::MapPoint>& point = points[i];
    if (point && !point->isBad() && point->beta() < min_point_beta && map.eraseMapPoint(ids[i])) ++culled;
  }
  return culled;
}

namespace {

/// Map::keyFrame() remembered over one culling pass: the redundancy test looks up every observer
/// of every point, and on a revisited map the same few dozen keyframes observe them all (each
/// Map::keyFrame() takes the map's lock, which tracking's searches share). Ids erased during the
/// pass are forgotten.
class KeyFrameLookup {
 public:
  explicit KeyFrameLookup(const map::Map& map) : map_(map) {}
  const map::KeyFrame* find(map::KeyFrameId id) {
    auto it = cache_.find(id);
    if (it == cache_.end()) it = cache_.emplace(id, map_.keyFrame(id)).first;
    return it->second.get();
  }
  void forget(map::KeyFrameId id) { cache_.erase(id); }

 private:
  const map::Map& map_;
  std::unordered_map<map::KeyFrameId, std::shared_ptr<map::KeyFrame>> cache_;
};

bool mostlyRedundant(const map::Map& map, const map::KeyFrame& kf, int min_other_observers, double ratio,
                     KeyFrameLookup& keyframes);

/// What culling `kf` does to the IMU chain: bridge it (both neighbours in time exist with
/// preintegrations spanning at most max_imu_span_s), cut it (kf and its next keyframe are at least
/// cut_imu_min_age_s older than `current`), or nothing allows the cull.
std::optional<map::Map::ImuLink> imuChainOnCulling(const map::Map& map, const map::KeyFrame& kf,
                                                   const map::KeyFrame& current,
                                                   const KeyFrameCullingOptions& options) {
  const std::shared_ptr<map::KeyFrame> previous = map.keyFrame(kf.previousKeyFrame());
  const std::shared_ptr<map::KeyFrame> next = map.keyFrame(kf.nextKeyFrame());
  if (!previous || !next || previous->isBad() || next->isBad()) return std::nullopt;
  if (kf.imuFromPrevious() && next->imuFromPrevious() && next->t_s() - previous->t_s() <= options.max_imu_span_s) {
    return map::Map::ImuLink::kMerge;
  }
  if (options.cut_imu_min_age_s > 0.0 && current.t_s() - next->t_s() >= options.cut_imu_min_age_s) {
    return map::Map::ImuLink::kCut;
  }
  return std::nullopt;
}

}  // namespace

// Stops as soon as the answer is certain: with w points judged so far, r of them redundant, and
// at most n left, the share can reach at most (r + n) / (w + n) (issue 32: on a revisited map
// every point has many observers, and most candidates fail early).
bool mostlyRedundant(const map::Map& map, const map::KeyFrame& kf, int min_other_observers, double ratio) {
  KeyFrameLookup keyframes(map);
  return mostlyRedundant(map, kf, min_other_observers, ratio, keyframes);
}

namespace {

bool mostlyRedundant(const map::Map& map, const map::KeyFrame& kf, int min_other_observers, double ratio,
                     KeyFrameLookup& keyframes) {
  // The keypoints judged: linked to a point and with depth.
  const std::vector<map::MapPointId> all_ids = kf.mapPoints();
  std::vector<int> judged;
  judged.reserve(all_ids.size());
  for (std::size_t i = 0; i < all_ids.size(); ++i) {
    if (all_ids[i].valid() && kf.depth_m(static_cast<int>(i)) > 0.0f) judged.push_back(static_cast<int>(i));
  }
  // Points are looked up a chunk at a time: most candidates fail within their first tens of points,
  // and one lookup takes a hash probe and a shared_ptr copy under the map's lock.
  constexpr std::size_t kChunk = 64;
  std::vector<map::MapPointId> chunk_ids;
  std::vector<std::shared_ptr<map::MapPoint>> points;
  int left = static_cast<int>(judged.size());
  int with_depth = 0;
  int redundant = 0;
  map::Observations observations;
  for (std::size_t j = 0; j < judged.size(); ++j) {
    // (Rounding is monotone, so the bound fails the ratio only if the share would.)
    if (static_cast<double>(redundant + left) / (with_depth + left) < ratio) return false;
    --left;
    if (j % kChunk == 0) {
      chunk_ids.clear();
      for (std::size_t c = j; c < std::min(j + kChunk, judged.size()); ++c) {
        chunk_ids.push_back(all_ids[static_cast<std::size_t>(judged[c])]);
      }
      map.mapPointsInto(chunk_ids, &points);
    }
    const std::shared_ptr<map::MapPoint>& point = points[j % kChunk];
    if (!point || point->isBad()) continue;
    ++with_depth;
    point->observationsInto(&observations);
    if (static_cast<int>(observations.size()) <= min_other_observers) continue;
    const int octave = kf.keypoints()[static_cast<std::size_t>(judged[j])].octave;
    int observers = 0;
    for (const auto& [other_id, index] : observations) {
      if (other_id == kf.id()) continue;
      const map::KeyFrame* other = keyframes.find(other_id);
      if (other == nullptr || index < 0 || index >= other->numKeypoints()) continue;
      if (other->keypoints()[static_cast<std::size_t>(index)].octave <= octave + 1 &&
          ++observers >= min_other_observers) {
        break;
      }
    }
    if (observers >= min_other_observers) ++redundant;
  }
  return with_depth > 0 && static_cast<double>(redundant) / with_depth >= ratio;
}

}  // namespace

std::vector<map::KeyFrameId> cullRedundantKeyFrames(map::Map& map, const map::KeyFrame& current,
                                                    const KeyFrameCullingOptions& options, int* cut_links) {
  std::vector<map::KeyFrameId> culled;
  if (map.numKeyFrames() <= options.min_map_keyframes) return culled;
  const std::vector<map::KeyFrameId> origins = map.originKeyFrames();
  KeyFrameLookup keyframes(map);
  for (const map::KeyFrameId id : current.bestCovisibles(options.max_candidates)) {
    // Only keyframes older than the one processed and its predecessor: tracking links its next
    // keyframe's IMU chain to the newest ones (threaded, tracking may be keyframes ahead).
    if (!(id < current.id()) || id == current.previousKeyFrame()) continue;
    if (std::find(origins.begin(), origins.end(), id) != origins.end()) continue;
    const std::shared_ptr<map::KeyFrame> kf = map.keyFrame(id);
    if (!kf || kf->isBad()) continue;
    map::Map::ImuLink imu_link = map::Map::ImuLink::kMerge;
    if (options.use_imu) {
      const std::optional<map::Map::ImuLink> allowed = imuChainOnCulling(map, *kf, current, options);
      if (!allowed) continue;
      imu_link = *allowed;
    }
    if (!mostlyRedundant(map, *kf, options.min_other_observers, options.redundant_ratio, keyframes)) continue;
    if (map.eraseKeyFrame(id, imu_link)) {
      keyframes.forget(id);
      culled.push_back(id);
      if (cut_links != nullptr && imu_link == map::Map::ImuLink::kCut) ++*cut_links;
    }
    if (map.numKeyFrames() <= options.min_map_keyframes) break;
  }
  return culled;
}

}  // namespace ltlo::mapping
