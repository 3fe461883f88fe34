#include "ltlo/map/keyframe.h"

#include <algorithm>

#include "bow/vocabulary.h"
#include "ltlo/core/assert.h"

namespace ltlo::map {

namespace {
bool byWeightThenId(const std::pair<KeyFrameId, int>& a, const std::pair<KeyFrameId, int>& b) {
  return a.second != b.second ? a.second > b.second : a.first < b.first;
}
}  // namespace

KeyFrame::KeyFrame(KeyFrameId id, MapId map, const Frame& frame)
    : id_(id),
      t_s_(frame.t_s()),
      camera_(frame.camera()),
      T_b_c_(frame.T_b_c()),
      features_(frame.features()),
      scale_factors_(frame.scaleFactors()),
      depth_m_(frame.depths_m()),
      p_c_(frame.points_c()),
      grid_(frame.grid()),
      segmentation_layout_(frame.segmentation()),
      keypoint_cluster_(frame.keypointClusters()),
      static_threshold_(frame.staticThreshold()),
      pre_map_rest_(frame.pre_map_rest),
      map_(map),
      has_bow_(frame.hasBow()),
      bow_vector_(frame.bowVector()),
      feature_vector_(frame.featureVector()),
      gamma_(frame.segmentation().gamma),
      T_w_b_(frame.T_w_b()),
      v_w_b_(frame.v_w_b()),
      bias_(frame.bias()),
      imu_from_previous_(frame.imu_from_last_keyframe),
      at_rest_(frame.at_rest),
      map_points_(static_cast<std::size_t>(frame.numKeypoints())) {
  LTLO_ASSERT(id.valid(), "a keyframe needs a valid id");
  static_area_ratio_ = segmentation_layout_.staticAreaRatio(static_threshold_);
}

bool KeyFrame::hasBow() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return has_bow_;
}
bow::BowVector KeyFrame::bowVector() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bow_vector_;
}
bow::FeatureVector KeyFrame::featureVector() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return feature_vector_;
}
void KeyFrame::setBow(bow::BowVector bow_vector, bow::FeatureVector feature_vector) {
  std::lock_guard<std::mutex> lock(mutex_);
  bow_vector_ = std::move(bow_vector);
  feature_vector_ = std::move(feature_vector);
  has_bow_ = true;
}

std::vector<int> KeyFrame::featuresInArea(float x_px, float y_px, float radius_px, int min_octave,
                                          int max_octave) const {
  return grid_.featuresInArea(features_.keypoints, x_px, y_px, radius_px, min_octave, max_octave);
}
void KeyFrame::featuresInArea(float x_px, float y_px, float radius_px, int min_octave, int max_octave,
                              std::vector<int>* found) const {
  grid_.featuresInArea(features_.keypoints, x_px, y_px, radius_px, min_octave, max_octave, found);
}

std::vector<double> KeyFrame::gamma() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return gamma_;
}

void KeyFrame::setGamma(std::vector<double> gamma) {
  ClusterSegmentation segmentation = segmentation_layout_;  // shares the images (cv::Mat), copies the tables
  segmentation.gamma = std::move(gamma);
  segmentation.validate();
  const double ratio = segmentation.staticAreaRatio(static_threshold_);
  std::lock_guard<std::mutex> lock(mutex_);
  LTLO_ASSERT(segmentation.gamma.size() == gamma_.size(), "keyframe " << id_ << " has " << gamma_.size()
                                                                      << " clusters, got " << segmentation.gamma.size()
                                                                      << " scores");
  gamma_ = std::move(segmentation.gamma);
  static_area_ratio_ = ratio;
}

bool KeyFrame::isStatic(int i) const {
  const int cluster = clusterOf(i);
  std::lock_guard<std::mutex> lock(mutex_);
  const double g =
      cluster >= 0 && cluster < static_cast<int>(gamma_.size()) ? gamma_[static_cast<std::size_t>(cluster)] : 1.0;
  return g >= static_threshold_;
}

std::vector<int> KeyFrame::staticKeypoints() const {
  std::lock_guard<std::mutex> lock(mutex_);
  ClusterSegmentation scores;  // gammaOf() only; labels are not needed
  scores.gamma = gamma_;
  std::vector<int> indices;
  for (int i = 0; i < numKeypoints(); ++i) {
    if (scores.gammaOf(clusterOf(i)) >= static_threshold_) indices.push_back(i);
  }
  return indices;
}

ClusterSegmentation KeyFrame::segmentation() const {
  ClusterSegmentation segmentation = segmentation_layout_;
  std::lock_guard<std::mutex> lock(mutex_);
  segmentation.gamma = gamma_;
  return segmentation;
}

double KeyFrame::staticAreaRatio() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_area_ratio_;
}

MapId KeyFrame::mapId() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return map_;
}
void KeyFrame::setMapId(MapId map) {
  std::lock_guard<std::mutex> lock(mutex_);
  map_ = map;
}
SE3 KeyFrame::T_w_b() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return T_w_b_;
}
SE3 KeyFrame::T_w_c() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return T_w_b_ * T_b_c_;
}
Vec3 KeyFrame::cameraCentre_w() const { return T_w_c().translation(); }
void KeyFrame::setPose_T_w_b(const SE3& T_w_b) {
  std::lock_guard<std::mutex> lock(mutex_);
  T_w_b_ = T_w_b;
}
Vec3 KeyFrame::v_w_b() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return v_w_b_;
}
void KeyFrame::setVelocity(const Vec3& v_w_b) {
  std::lock_guard<std::mutex> lock(mutex_);
  v_w_b_ = v_w_b;
}
imu::ImuBias KeyFrame::bias() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bias_;
}
void KeyFrame::setBias(const imu::ImuBias& bias) {
  std::lock_guard<std::mutex> lock(mutex_);
  bias_ = bias;
}
KeyFrameId KeyFrame::previousKeyFrame() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return previous_;
}
KeyFrameId KeyFrame::nextKeyFrame() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return next_;
}
void KeyFrame::setPreviousKeyFrame(KeyFrameId id) {
  std::lock_guard<std::mutex> lock(mutex_);
  previous_ = id;
}
void KeyFrame::setNextKeyFrame(KeyFrameId id) {
  std::lock_guard<std::mutex> lock(mutex_);
  next_ = id;
}
std::optional<imu::Preintegrated> KeyFrame::imuFromPrevious() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return imu_from_previous_;
}
std::optional<KeyFrame::ImuLinkTiming> KeyFrame::imuLinkTiming() const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!imu_from_previous_) return std::nullopt;
  return ImuLinkTiming{imu_from_previous_->dt_s(), imu_from_previous_->shiftEnd_s()};
}
void KeyFrame::setImuFromPrevious(std::optional<imu::Preintegrated> preintegration) {
  std::lock_guard<std::mutex> lock(mutex_);
  imu_from_previous_ = std::move(preintegration);
}

MapPointId KeyFrame::mapPoint(int i) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return map_points_.at(static_cast<std::size_t>(i));
}
std::vector<MapPointId> KeyFrame::mapPoints() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return map_points_;
}
int KeyFrame::numObservations() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(
      std::count_if(map_points_.begin(), map_points_.end(), [](MapPointId p) { return p.valid(); }));
}
bool KeyFrame::setMapPoint(int i, MapPointId point) {
  LTLO_ASSERT(i >= 0 && i < numKeypoints(), "keypoint " << i << " out of [0, " << numKeypoints() << ") in " << id_);
  std::lock_guard<std::mutex> lock(mutex_);
  if (bad_) return false;
  map_points_[static_cast<std::size_t>(i)] = point;
  return true;
}
void KeyFrame::eraseMapPoint(int i, MapPointId point) {
  std::lock_guard<std::mutex> lock(mutex_);
  MapPointId& slot = map_points_.at(static_cast<std::size_t>(i));
  if (slot == point) slot = MapPointId();
}

std::vector<std::pair<KeyFrameId, int>> KeyFrame::covisibles() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return ordered_covisibles_;
}
std::vector<KeyFrameId> KeyFrame::bestCovisibles(std::size_t max_count) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<KeyFrameId> ids;
  for (std::size_t k = 0; k < ordered_covisibles_.size() && k < max_count; ++k)
    ids.push_back(ordered_covisibles_[k].first);
  return ids;
}
std::vector<KeyFrameId> KeyFrame::covisiblesWithWeightAtLeast(int min_weight) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<KeyFrameId> ids;
  for (const auto& [id, w] : ordered_covisibles_) {
    if (w < min_weight) break;
    ids.push_back(id);
  }
  return ids;
}
int KeyFrame::weight(KeyFrameId other) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = connections_.find(other);
  return it == connections_.end() ? 0 : it->second;
}
void KeyFrame::addConnection(KeyFrameId other, int weight) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (bad_ || other == id_) return;
  if (weight <= 0) {
    connections_.erase(other);
  } else {
    connections_[other] = weight;
  }
  sortCovisiblesLocked();
}
void KeyFrame::eraseConnection(KeyFrameId other) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (connections_.erase(other) > 0) sortCovisiblesLocked();
}
void KeyFrame::replaceConnections(std::unordered_map<KeyFrameId, int> weights) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (bad_) return;
  connections_ = std::move(weights);
  sortCovisiblesLocked();
}
void KeyFrame::sortCovisiblesLocked() {
  ordered_covisibles_.assign(connections_.begin(), connections_.end());
  std::sort(ordered_covisibles_.begin(), ordered_covisibles_.end(), byWeightThenId);
}

KeyFrameId KeyFrame::parent() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return parent_;
}
std::vector<KeyFrameId> KeyFrame::children() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return children_;
}
std::vector<KeyFrameId> KeyFrame::loopEdges() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return loop_edges_;
}
void KeyFrame::addLoopEdge(KeyFrameId other) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (std::find(loop_edges_.begin(), loop_edges_.end(), other) == loop_edges_.end()) loop_edges_.push_back(other);
}
void KeyFrame::setParent(KeyFrameId parent) {
  LTLO_ASSERT(parent != id_, "keyframe " << id_ << " cannot be its own parent");
  std::lock_guard<std::mutex> lock(mutex_);
  parent_ = parent;
}
bool KeyFrame::addChild(KeyFrameId child) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (bad_) return false;
  if (std::find(children_.begin(), children_.end(), child) == children_.end()) children_.push_back(child);
  return true;
}
void KeyFrame::eraseChild(KeyFrameId child) {
  std::lock_guard<std::mutex> lock(mutex_);
  children_.erase(std::remove(children_.begin(), children_.end(), child), children_.end());
}
bool KeyFrame::isBad() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bad_;
}
bool KeyFrame::setBad() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (bad_) return false;
  bad_ = true;
  return true;
}

std::shared_ptr<KeyFrame> KeyFrame::culledParent() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return culled_parent_;
}

SE3 KeyFrame::T_parent_this() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return T_parent_this_;
}

void KeyFrame::setCulledParent(std::shared_ptr<KeyFrame> parent, const SE3& T_parent_this) {
  std::lock_guard<std::mutex> lock(mutex_);
  culled_parent_ = std::move(parent);
  T_parent_this_ = T_parent_this;
}

bool KeyFrame::setCulled(std::shared_ptr<KeyFrame> parent, const SE3& T_parent_this) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (bad_) return false;
  bad_ = true;
  culled_parent_ = std::move(parent);
  T_parent_this_ = T_parent_this;
  return true;
}

void KeyFrame::replaceCulledParent(std::shared_ptr<KeyFrame> parent) {
  std::lock_guard<std::mutex> lock(mutex_);
  LTLO_ASSERT(bad_, "only a culled keyframe has a culled parent to replace");
  LTLO_ASSERT(parent && culled_parent_ && parent->id() == culled_parent_->id(),
              "a culled parent is replaced by a stand-in of itself");
  culled_parent_ = std::move(parent);
}

std::shared_ptr<KeyFrame> culledStandIn(const KeyFrame& culled) {
  std::shared_ptr<KeyFrame> parent;
  SE3 T_parent_this;
  SE3 T_w_b;
  Vec3 v_w_b;
  imu::ImuBias bias;
  MapId map;
  {
    std::lock_guard<std::mutex> lock(culled.mutex_);
    LTLO_ASSERT(culled.bad_, "a stand-in is made of a culled keyframe");
    parent = culled.culled_parent_;
    T_parent_this = culled.T_parent_this_;
    T_w_b = culled.T_w_b_;
    v_w_b = culled.v_w_b_;
    bias = culled.bias_;
    map = culled.map_;
  }
  Frame state(culled.t_s(), culled.camera(), culled.T_b_c(), features::OrbFeatures{}, {}, {1.0f});
  state.setPose_T_w_b(T_w_b);
  state.setVelocity(v_w_b);
  state.setBias(bias);
  auto stand_in = std::make_shared<KeyFrame>(culled.id(), map, state);
  stand_in->setCulled(std::move(parent), T_parent_this);
  return stand_in;
}

SE3 latestPose_T_w_b(const KeyFrame& kf) {
  // Walk up the culled chain (each link is older and was alive when its child was culled).
  SE3 T_last_kf;  // T_{last visited}^-1 T_kf, composed right to left
  const KeyFrame* current = &kf;
  std::shared_ptr<KeyFrame> hold;
  while (current->isBad()) {
    std::shared_ptr<KeyFrame> parent = current->culledParent();
    if (!parent) break;  // culled without a parent: its pose at culling time is all we have
    T_last_kf = current->T_parent_this() * T_last_kf;
    hold = std::move(parent);
    current = hold.get();
  }
  return current->T_w_b() * T_last_kf;
}

std::pair<bow::BowVector, bow::FeatureVector> staticKeypointsBow(const KeyFrame& kf,
                                                                const bow::Vocabulary& vocabulary) {
  constexpr int kFeatureDepth = 2;
  const std::vector<int> indices = kf.staticKeypoints();
  std::vector<features::Descriptor> descriptors;
  descriptors.reserve(indices.size());
  for (const int i : indices) descriptors.push_back(kf.descriptors()[static_cast<std::size_t>(i)]);
  bow::BowVector bow_vector;
  bow::FeatureVector by_position;
  vocabulary.transform(descriptors, &bow_vector, &by_position, kFeatureDepth);
  bow::FeatureVector feature_vector;
  for (auto& [node, positions] : by_position) {
    std::vector<std::uint32_t>& keypoints = feature_vector[node];
    keypoints.reserve(positions.size());
    for (const std::uint32_t position : positions) keypoints.push_back(static_cast<std::uint32_t>(indices[position]));
  }
  return {std::move(bow_vector), std::move(feature_vector)};
}

}  // namespace ltlo::map
