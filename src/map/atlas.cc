#include "ltlo/map/atlas.h"

#include <algorithm>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"

namespace ltlo::map {

Atlas::Atlas(std::size_t num_words) : ids_(std::make_shared<IdSource>()), database_(num_words) {
  std::lock_guard<std::mutex> lock(mutex_);
  createNewMapLocked();
}

Map& Atlas::createNewMap() {
  std::lock_guard<std::mutex> lock(mutex_);
  return createNewMapLocked();
}

Map& Atlas::createNewMapLocked() {
  const MapId id = ids_->nextMapId();
  auto map = std::make_unique<Map>(id, ids_);
  Map& ref = *map;
  maps_.emplace(id, std::move(map));
  active_ = id;
  return ref;
}

Map& Atlas::activeMap() {
  std::lock_guard<std::mutex> lock(mutex_);
  return *maps_.at(active_);
}

MapId Atlas::activeMapId() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return active_;
}

void Atlas::setActiveMap(MapId id) {
  std::lock_guard<std::mutex> lock(mutex_);
  LTLO_ASSERT(maps_.count(id) > 0, "atlas has no map " << id);
  active_ = id;
}

Map* Atlas::map(MapId id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = maps_.find(id);
  return it == maps_.end() ? nullptr : it->second.get();
}

std::vector<MapId> Atlas::mapIds() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<MapId> ids;
  for (const auto& entry : maps_) {
    if (std::find(merged_.begin(), merged_.end(), entry.first) == merged_.end()) ids.push_back(entry.first);
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

MapId Atlas::resolve(MapId id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = merged_into_.find(id); it != merged_into_.end(); it = merged_into_.find(id)) id = it->second;
  return id;
}

void Atlas::mergeMaps(MapId source, MapId target, const SE3& T_target_source) {
  std::lock_guard<std::mutex> lock(mutex_);
  LTLO_ASSERT(source != target, "cannot merge map " << source << " into itself");
  LTLO_ASSERT(maps_.count(source) > 0 && maps_.count(target) > 0,
              "merge of unknown maps " << source << " -> " << target);
  Map& source_map = *maps_.at(source);
  Map& target_map = *maps_.at(target);
  Map::Content content = source_map.takeContent();
  const Mat3 R_target_source = T_target_source.rotationMatrix();
  for (const auto& [id, kf] : content.keyframes) {
    kf->setPose_T_w_b(T_target_source * kf->T_w_b());
    kf->setVelocity(R_target_source * kf->v_w_b());
    kf->setMapId(target);
  }
  for (const auto& [id, point] : content.points) {
    point->setPosition(T_target_source * point->p_w());
    point->setNormalAndDistances(R_target_source * point->normal_w(), point->minDistance_m(), point->maxDistance_m());
  }
  log::info("atlas: merged map ", source, " (", content.keyframes.size(), " keyframes, ", content.points.size(),
            " points) into map ", target);
  target_map.addContent(std::move(content));
  source_map.bumpVersion();
  target_map.bumpVersion();
  merged_.push_back(source);
  merged_into_[source] = target;
  if (active_ == source) active_ = target;
}

}  // namespace ltlo::map
