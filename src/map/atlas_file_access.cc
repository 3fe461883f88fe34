#include "atlas_file_access.h"

#include <algorithm>

#include "ltlo/core/assert.h"

namespace ltlo::map {

std::unique_ptr<Atlas> AtlasFileAccess::emptyAtlas(std::size_t num_words) {
  auto atlas = std::make_unique<Atlas>(num_words);
  std::lock_guard<std::mutex> lock(atlas->mutex_);
  atlas->maps_.clear();
  atlas->active_ = MapId();
  return atlas;
}

Map& AtlasFileAccess::addMap(Atlas& atlas, MapId id) {
  std::lock_guard<std::mutex> lock(atlas.mutex_);
  LTLO_ASSERT(atlas.maps_.count(id) == 0, "atlas already has map " << id);
  auto map = std::make_unique<Map>(id, atlas.ids_);
  Map& ref = *map;
  atlas.maps_.emplace(id, std::move(map));
  if (!atlas.active_.valid()) atlas.active_ = id;
  return ref;
}

IdSource& AtlasFileAccess::ids(Atlas& atlas) { return *atlas.ids_; }

bool AtlasFileAccess::createdKeyFrame(const Map& map) {
  std::lock_guard<std::mutex> lock(map.mutex_);
  return map.created_keyframe_;
}

void AtlasFileAccess::insert(Map& map, std::shared_ptr<KeyFrame> kf) {
  std::lock_guard<std::mutex> lock(map.mutex_);
  const KeyFrameId id = kf->id();
  map.keyframes_.emplace(id, std::move(kf));
}

void AtlasFileAccess::insert(Map& map, std::shared_ptr<MapPoint> point) {
  std::lock_guard<std::mutex> lock(map.mutex_);
  const MapPointId id = point->id();
  map.points_.emplace(id, std::move(point));
}

void AtlasFileAccess::setOrigins(Map& map, std::vector<KeyFrameId> origins, bool created_keyframe) {
  std::lock_guard<std::mutex> lock(map.mutex_);
  map.origins_ = std::move(origins);
  map.created_keyframe_ = created_keyframe;
}

void AtlasFileAccess::setTree(KeyFrame& kf, KeyFrameId parent, const std::vector<KeyFrameId>& children) {
  std::lock_guard<std::mutex> lock(kf.mutex_);
  kf.parent_ = parent;
  kf.children_ = children;
}

void AtlasFileAccess::setConnections(KeyFrame& kf, std::unordered_map<KeyFrameId, int> weights) {
  kf.replaceConnections(std::move(weights));
}

void AtlasFileAccess::setCounts(MapPoint& point, int num_visible, int num_found) {
  std::lock_guard<std::mutex> lock(point.mutex_);
  point.num_visible_ = num_visible;
  point.num_found_ = num_found;
}

std::vector<MapId> AtlasFileAccess::allMapIds(const Atlas& atlas) {
  std::lock_guard<std::mutex> lock(atlas.mutex_);
  std::vector<MapId> ids;
  for (const auto& entry : atlas.maps_) ids.push_back(entry.first);
  std::sort(ids.begin(), ids.end());
  return ids;
}

std::vector<std::pair<MapId, MapId>> AtlasFileAccess::merges(const Atlas& atlas) {
  std::lock_guard<std::mutex> lock(atlas.mutex_);
  std::vector<std::pair<MapId, MapId>> merges;
  for (const MapId source : atlas.merged_) merges.emplace_back(source, atlas.merged_into_.at(source));
  return merges;
}

Map& AtlasFileAccess::addMergedMap(Atlas& atlas, MapId id, MapId target) {
  Map& map = addMap(atlas, id);
  std::lock_guard<std::mutex> lock(atlas.mutex_);
  atlas.merged_.push_back(id);
  atlas.merged_into_[id] = target;
  return map;
}

void AtlasFileAccess::setVersion(Map& map, std::uint64_t version) { map.version_.store(version); }

void AtlasFileAccess::setAtRest(KeyFrame& kf, bool at_rest) {
  std::lock_guard<std::mutex> lock(kf.mutex_);
  kf.at_rest_ = at_rest;
}

std::shared_ptr<KeyFrame> AtlasFileAccess::culledKeyFrame(KeyFrameId id, MapId map, const Frame& state) {
  auto kf = std::make_shared<KeyFrame>(id, map, state);
  kf->setBad();
  return kf;
}

void AtlasFileAccess::setCulledParent(KeyFrame& kf, std::shared_ptr<KeyFrame> parent, const SE3& T_parent_this) {
  kf.setCulledParent(std::move(parent), T_parent_this);
}

}  // namespace ltlo::map
