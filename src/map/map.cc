#include "ltlo/map/map.h"

#include <algorithm>
#include <set>

#include "ltlo/core/assert.h"

namespace ltlo::map {

namespace {
template <typename Id, typename T>
std::vector<std::shared_ptr<T>> sortedValues(const std::unordered_map<Id, std::shared_ptr<T>>& container) {
  std::vector<std::shared_ptr<T>> values;
  values.reserve(container.size());
  for (const auto& entry : container) values.push_back(entry.second);
  std::sort(values.begin(), values.end(), [](const auto& a, const auto& b) { return a->id() < b->id(); });
  return values;
}
}  // namespace

Map::Map(MapId id, std::shared_ptr<IdSource> ids) : id_(id), ids_(std::move(ids)) {
  LTLO_ASSERT(ids_ != nullptr, "a map needs an id source");
}

Map::Map() : Map(MapId(0), std::make_shared<IdSource>()) {}

std::shared_ptr<KeyFrame> Map::createKeyFrame(const Frame& frame) {
  auto kf = std::make_shared<KeyFrame>(ids_->nextKeyFrameId(), id_, frame);
  std::lock_guard<std::mutex> lock(mutex_);
  if (!created_keyframe_) origins_.push_back(kf->id());  // even if a merge filled the map first
  created_keyframe_ = true;
  keyframes_.emplace(kf->id(), kf);
  return kf;
}

std::shared_ptr<MapPoint> Map::createMapPoint(const Vec3& p_w, KeyFrameId reference) {
  auto point = std::make_shared<MapPoint>(ids_->nextMapPointId(), p_w, reference);
  std::lock_guard<std::mutex> lock(mutex_);
  points_.emplace(point->id(), point);
  return point;
}

std::shared_ptr<KeyFrame> Map::keyFrame(KeyFrameId id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : it->second;
}
std::shared_ptr<MapPoint> Map::mapPoint(MapPointId id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = points_.find(id);
  return it == points_.end() ? nullptr : it->second;
}
void Map::mapPointsInto(const std::vector<MapPointId>& ids, std::vector<std::shared_ptr<MapPoint>>* out) const {
  out->resize(ids.size());
  std::lock_guard<std::mutex> lock(mutex_);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const auto it = ids[i].valid() ? points_.find(ids[i]) : points_.end();
    (*out)[i] = it == points_.end() ? nullptr : it->second;
  }
}
std::vector<std::shared_ptr<KeyFrame>> Map::keyFrames() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return sortedValues(keyframes_);
}
std::vector<std::shared_ptr<MapPoint>> Map::mapPoints() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return sortedValues(points_);
}
void Map::setOrigin(const MapOrigin& origin) {
  std::lock_guard<std::mutex> lock(mutex_);
  origin_ = origin;
}

std::optional<MapOrigin> Map::origin() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return origin_;
}

std::size_t Map::numKeyFrames() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return keyframes_.size();
}
std::size_t Map::numMapPoints() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return points_.size();
}
std::vector<KeyFrameId> Map::originKeyFrames() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return origins_;
}
KeyFrameId Map::gaugeKeyFrame() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return origins_.empty() ? KeyFrameId() : origins_.front();
}
KeyFrameId Map::moveGaugeTo(KeyFrameId id) {
  std::lock_guard<std::mutex> lock(mutex_);
  LTLO_ASSERT(keyframes_.count(id) > 0, "moveGaugeTo: keyframe " << id << " is not in map " << id_);
  const KeyFrameId previous = origins_.empty() ? KeyFrameId() : origins_.front();
  if (previous == id) return previous;
  origins_.erase(std::remove(origins_.begin(), origins_.end(), id), origins_.end());
  if (!origins_.empty()) origins_.front() = id;
  else origins_.push_back(id);
  return previous;
}
bool Map::isOrigin(KeyFrameId id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return std::find(origins_.begin(), origins_.end(), id) != origins_.end();
}

bool Map::addObservation(KeyFrame& kf, int keypoint_index, MapPoint& point) {
  // Both ends under their locks in the documented order, so a concurrent erase of either sees
  // the link on both ends or on neither.
  std::lock_guard<std::mutex> kf_lock(kf.mutex_);
  if (kf.bad_) return false;
  LTLO_ASSERT(keypoint_index >= 0 && keypoint_index < kf.numKeypoints(),
              "keypoint " << keypoint_index << " out of [0, " << kf.numKeypoints() << ") in " << kf.id());
  MapPointId& slot = kf.map_points_[static_cast<std::size_t>(keypoint_index)];
  if (slot.valid() && slot != point.id()) return false;  // the keypoint already has another point
  std::lock_guard<std::mutex> point_lock(point.mutex_);
  if (point.bad_) return false;
  const int seen_at = point.indexInLocked(kf.id());
  if (seen_at >= 0 && seen_at != keypoint_index) return false;  // seen at another keypoint
  kf.map_points_[static_cast<std::size_t>(keypoint_index)] = point.id();
  point.setObservationLocked(kf.id(), keypoint_index);
  if (!point.reference_.valid()) point.reference_ = kf.id();
  return true;
}

void Map::eraseObservation(KeyFrame& kf, int keypoint_index) {
  const MapPointId point_id = kf.mapPoint(keypoint_index);
  if (!point_id.valid()) return;
  kf.eraseMapPoint(keypoint_index, point_id);
  if (const std::shared_ptr<MapPoint> point = mapPoint(point_id)) point->eraseObservation(kf.id());
}

void Map::updateConnections(KeyFrame& kf) {
  // Serialised with culling: an edge computed here must not point at a keyframe erased meanwhile.
  std::lock_guard<std::mutex> topology(topology_mutex_);
  std::unordered_map<KeyFrameId, int> shared_counts;
  for (MapPointId point_id : kf.mapPoints()) {
    if (!point_id.valid()) continue;
    const std::shared_ptr<MapPoint> point = mapPoint(point_id);
    if (!point || point->isBad()) continue;
    for (const auto& [other, index] : point->observations()) {
      if (other != kf.id()) ++shared_counts[other];
    }
  }
  std::unordered_map<KeyFrameId, std::shared_ptr<KeyFrame>> others;
  for (const auto& [other_id, count] : shared_counts) {
    std::shared_ptr<KeyFrame> other = keyFrame(other_id);
    if (other && !other->isBad()) others.emplace(other_id, std::move(other));
  }
  KeyFrameId strongest;
  int strongest_weight = 0;
  std::unordered_map<KeyFrameId, int> weights;
  for (const auto& [other_id, other] : others) {
    const int w = shared_counts[other_id];
    if (w > strongest_weight || (w == strongest_weight && other_id < strongest)) {
      strongest = other_id;
      strongest_weight = w;
    }
    if (w >= kMinCovisibilityWeight) weights.emplace(other_id, w);
  }
  if (weights.empty() && strongest.valid()) weights.emplace(strongest, strongest_weight);
  for (const auto& [other_id, w] : weights) others[other_id]->addConnection(kf.id(), w);
  kf.replaceConnections(weights);

  if (kf.parent().valid() || isOrigin(kf.id()) || kf.isBad()) return;
  // The parent is the best covisible among the older keyframes (ids grow with creation), so the
  // tree never forms a cycle, whatever order connections are updated in.
  for (const auto& [candidate_id, w] : kf.covisibles()) {  // best first; skip any culled meanwhile
    if (!(candidate_id < kf.id())) continue;
    const std::shared_ptr<KeyFrame> candidate = keyFrame(candidate_id);
    if (candidate && candidate->addChild(kf.id())) {
      kf.setParent(candidate_id);
      return;
    }
  }
  // No covisible yet (a keyframe tracking placed by the IMU alone, its points all new): its
  // previous keyframe in the IMU chain, which the inertial edge ties it to.
  const KeyFrameId previous = kf.previousKeyFrame();
  if (previous.valid() && previous < kf.id()) {
    const std::shared_ptr<KeyFrame> candidate = keyFrame(previous);
    if (candidate && candidate->addChild(kf.id())) kf.setParent(previous);
  }
}

void Map::observersInto(const Observations& observations, std::vector<std::shared_ptr<KeyFrame>>* out) const {
  out->resize(observations.size());
  std::lock_guard<std::mutex> lock(mutex_);
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const auto it = keyframes_.find(observations[i].first);
    (*out)[i] = it == keyframes_.end() ? nullptr : it->second;
  }
}

void Map::updateDescriptor(MapPoint& point) {
  // The median depends on the observations alone (a culled observer's are erased with it): one
  // unchanged since the last update keeps its descriptor (issue 32: a point of a revisited room has
  // tens of observers, and fusion asks for every point of the keyframe).
  if (point.descriptorCurrent()) return;
  std::vector<features::Descriptor> descriptors;
  Observations observations;
  const std::uint64_t version = point.versionedObservationsInto(&observations);
  std::vector<std::shared_ptr<KeyFrame>> observers;
  observersInto(observations, &observers);
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const std::shared_ptr<KeyFrame>& kf = observers[i];
    const int index = observations[i].second;
    if (kf && !kf->isBad()) descriptors.push_back(kf->descriptors()[static_cast<std::size_t>(index)]);
  }
  const int best = MapPoint::medianDescriptorIndex(descriptors);
  if (best >= 0) point.setDescriptor(descriptors[static_cast<std::size_t>(best)], version);
}

void Map::updateNormalAndDistances(MapPoint& point) {
  const Vec3 p_w = point.p_w();
  const KeyFrameId reference_id = point.referenceKeyFrame();
  Vec3 normal_sum = Vec3::Zero();
  int num_views = 0;
  std::shared_ptr<KeyFrame> reference;
  int reference_index = -1;
  const Observations observations = point.observations();
  std::vector<std::shared_ptr<KeyFrame>> observers;
  observersInto(observations, &observers);
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const auto& [kf_id, index] = observations[i];
    const std::shared_ptr<KeyFrame>& kf = observers[i];
    if (!kf) continue;
    const Vec3 ray = p_w - kf->cameraCentre_w();
    if (ray.norm() <= 0.0) continue;
    normal_sum += ray.normalized();
    ++num_views;
    if (kf_id == reference_id) {
      reference = kf;
      reference_index = index;
    }
  }
  if (num_views == 0 || !reference) return;
  const double distance_m = (p_w - reference->cameraCentre_w()).norm();
  const std::vector<float>& scales = reference->scaleFactors();
  const int octave = reference->keypoints()[static_cast<std::size_t>(reference_index)].octave;
  // A descriptor seen at `octave` from distance d matches at level 0 up to d * scale(octave) and
  // at the coarsest level down to that over scale(last level).
  const double max_distance_m = distance_m * scales[static_cast<std::size_t>(octave)];
  const double min_distance_m = max_distance_m / scales.back();
  point.setNormalAndDistances(normal_sum.normalized(), min_distance_m, max_distance_m);
}

bool Map::eraseKeyFrame(KeyFrameId id, ImuLink imu_link) {
  std::lock_guard<std::mutex> topology(topology_mutex_);
  const std::shared_ptr<KeyFrame> kf = keyFrame(id);
  if (!kf || isOrigin(id)) return false;
  // Bad and linked to its parent at culling in one step (KeyFrame::setCulled): a holder that sees it
  // bad follows the link (latestPose_T_w_b, culledStandIn).
  const KeyFrameId parent_id = kf->parent();
  const std::shared_ptr<KeyFrame> parent_at_culling = keyFrame(parent_id);
  const SE3 T_parent_this = parent_at_culling ? parent_at_culling->T_w_b().inverse() * kf->T_w_b() : SE3();
  if (!kf->setCulled(parent_at_culling, T_parent_this)) return false;

  for (const auto& [other_id, w] : kf->covisibles()) {
    if (const std::shared_ptr<KeyFrame> other = keyFrame(other_id)) other->eraseConnection(id);
  }
  for (MapPointId point_id : kf->mapPoints()) {
    if (!point_id.valid()) continue;
    const std::shared_ptr<MapPoint> point = mapPoint(point_id);
    if (point && point->eraseObservation(id) == 0) eraseMapPointUnserialised(point_id);
  }

  // Spanning-tree repair: grow the set of possible parents from kf's parent; at each step attach the
  // child with the strongest covisibility edge to any member, which then becomes a member itself.
  std::vector<KeyFrameId> orphans = kf->children();
  std::set<KeyFrameId> parent_candidates{parent_id};
  while (!orphans.empty()) {
    int best_weight = 0;
    std::size_t best_orphan = orphans.size();
    KeyFrameId best_parent;
    for (std::size_t k = 0; k < orphans.size(); ++k) {
      const std::shared_ptr<KeyFrame> child = keyFrame(orphans[k]);
      if (!child) continue;
      for (const auto& [candidate, w] : child->covisibles()) {
        if (w > best_weight && parent_candidates.count(candidate) > 0) {
          best_weight = w;
          best_orphan = k;
          best_parent = candidate;
        }
      }
    }
    if (best_orphan == orphans.size()) break;
    const std::shared_ptr<KeyFrame> child = keyFrame(orphans[best_orphan]);
    const std::shared_ptr<KeyFrame> new_parent = keyFrame(best_parent);
    if (new_parent && new_parent->addChild(child->id())) {
      child->setParent(best_parent);
      parent_candidates.insert(child->id());
    } else {
      parent_candidates.erase(best_parent);  // culled meanwhile: try the others
      continue;
    }
    orphans.erase(orphans.begin() + static_cast<long>(best_orphan));
  }
  const std::shared_ptr<KeyFrame> parent = keyFrame(parent_id);
  for (KeyFrameId orphan_id : orphans) {  // no covisibility with the candidates: fall back to kf's parent
    const std::shared_ptr<KeyFrame> orphan = keyFrame(orphan_id);
    if (!orphan) continue;
    if (parent && parent->addChild(orphan_id)) {
      orphan->setParent(parent_id);
    } else {
      orphan->setParent(KeyFrameId());
    }
  }
  if (parent) parent->eraseChild(id);

  // IMU chain: previous -> next, with the two preintegrations merged into one (or none: a cut).
  const KeyFrameId previous_id = kf->previousKeyFrame();
  const KeyFrameId next_id = kf->nextKeyFrame();
  const std::shared_ptr<KeyFrame> previous = keyFrame(previous_id);
  const std::shared_ptr<KeyFrame> next = keyFrame(next_id);
  if (previous) previous->setNextKeyFrame(next ? next_id : KeyFrameId());
  if (next) {
    next->setPreviousKeyFrame(previous ? previous_id : KeyFrameId());
    const std::optional<imu::Preintegrated> first = kf->imuFromPrevious();
    const std::optional<imu::Preintegrated> second = next->imuFromPrevious();
    if (imu_link == ImuLink::kCut) {
      next->setImuFromPrevious(std::nullopt);
    } else if (previous && first && second) {
      next->setImuFromPrevious(imu::Preintegrated::merged(*first, *second));
    } else if (!previous) {
      next->setImuFromPrevious(std::nullopt);
    }
  }

  std::lock_guard<std::mutex> lock(mutex_);
  keyframes_.erase(id);
  return true;
}

bool Map::eraseMapPoint(MapPointId id) {
  std::lock_guard<std::mutex> topology(topology_mutex_);
  if (!mapPoint(id)) return false;
  eraseMapPointUnserialised(id);
  return true;
}

void Map::eraseMapPointUnserialised(MapPointId id) {
  const std::shared_ptr<MapPoint> point = mapPoint(id);
  if (!point) return;
  if (const std::optional<Observations> observations = point->setBad(MapPointId())) {
    for (const auto& [kf_id, index] : *observations) {
      if (const std::shared_ptr<KeyFrame> kf = keyFrame(kf_id)) kf->eraseMapPoint(index, id);
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  points_.erase(id);
}

bool Map::replaceMapPoint(MapPointId old_id, MapPointId replacement) {
  std::lock_guard<std::mutex> topology(topology_mutex_);
  if (old_id == replacement) return false;
  const std::shared_ptr<MapPoint> old_point = mapPoint(old_id);
  const std::shared_ptr<MapPoint> new_point = mapPoint(replacement);
  if (!old_point || !new_point || new_point->isBad()) return false;
  const std::optional<Observations> observations = old_point->setBad(replacement);
  if (!observations) return false;
  for (const auto& [kf_id, index] : *observations) {
    const std::shared_ptr<KeyFrame> kf = keyFrame(kf_id);
    if (!kf) continue;
    kf->eraseMapPoint(index, old_id);
    if (!new_point->indexIn(kf_id)) addObservation(*kf, index, *new_point);
  }
  new_point->increaseVisible(old_point->numVisible());
  new_point->increaseFound(old_point->numFound());
  updateDescriptor(*new_point);
  std::lock_guard<std::mutex> lock(mutex_);
  points_.erase(old_id);
  return true;
}

void Map::setReferenceMapPoints(std::vector<MapPointId> points) {
  std::lock_guard<std::mutex> lock(mutex_);
  reference_points_ = std::move(points);
}
std::vector<MapPointId> Map::referenceMapPoints() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return reference_points_;
}

Map::Content Map::takeContent() {
  Content content;
  std::lock_guard<std::mutex> lock(mutex_);
  content.keyframes.swap(keyframes_);
  content.points.swap(points_);
  content.origins.swap(origins_);
  reference_points_.clear();
  return content;
}

void Map::addContent(Content content) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& entry : content.keyframes) keyframes_.insert(std::move(entry));
  for (auto& entry : content.points) points_.insert(std::move(entry));
  origins_.insert(origins_.end(), content.origins.begin(), content.origins.end());
}

}  // namespace ltlo::map
