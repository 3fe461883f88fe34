#include "ltlo/map/map_point.h"

#include <algorithm>
#include <cmath>

#include "ltlo/core/assert.h"
#include "ltlo/features/matching.h"

namespace ltlo::map {

MapPoint::MapPoint(MapPointId id, const Vec3& p_w, KeyFrameId reference) : id_(id), p_w_(p_w), reference_(reference) {
  LTLO_ASSERT(id.valid(), "a map point needs a valid id");
  LTLO_ASSERT(p_w.allFinite(), "map point " << id << " at non-finite position " << p_w.transpose());
}

Vec3 MapPoint::p_w() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return p_w_;
}
void MapPoint::setPosition(const Vec3& p_w) {
  LTLO_ASSERT(p_w.allFinite(), "map point " << id_ << " moved to non-finite position " << p_w.transpose());
  std::lock_guard<std::mutex> lock(mutex_);
  p_w_ = p_w;
}

namespace {

/// The first observation whose keyframe is not before `kf` (the list is sorted by keyframe id).
Observations::const_iterator lowerBound(const Observations& observations, KeyFrameId kf) {
  return std::lower_bound(observations.begin(), observations.end(), kf,
                          [](const std::pair<KeyFrameId, int>& entry, KeyFrameId id) { return entry.first < id; });
}

}  // namespace

Observations MapPoint::observations() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return observations_;
}
void MapPoint::observationsInto(Observations* out) const {
  std::lock_guard<std::mutex> lock(mutex_);
  out->assign(observations_.begin(), observations_.end());
}
int MapPoint::numObservations() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(observations_.size());
}
std::optional<int> MapPoint::indexIn(KeyFrameId kf) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const int index = indexInLocked(kf);
  if (index < 0) return std::nullopt;
  return index;
}
int MapPoint::indexInLocked(KeyFrameId kf) const {
  const auto it = lowerBound(observations_, kf);
  return it != observations_.end() && it->first == kf ? it->second : -1;
}
void MapPoint::setObservationLocked(KeyFrameId kf, int keypoint_index) {
  const auto it = lowerBound(observations_, kf);
  if (it != observations_.end() && it->first == kf) {
    observations_[static_cast<std::size_t>(it - observations_.begin())].second = keypoint_index;
  } else {
    observations_.insert(it, {kf, keypoint_index});
  }
  ++observations_version_;
}
KeyFrameId MapPoint::referenceKeyFrame() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return reference_;
}

bool MapPoint::addObservation(KeyFrameId kf, int keypoint_index) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (bad_) return false;
  setObservationLocked(kf, keypoint_index);
  if (!reference_.valid()) reference_ = kf;
  return true;
}

int MapPoint::eraseObservation(KeyFrameId kf) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = lowerBound(observations_, kf);
  if (it != observations_.end() && it->first == kf) {
    observations_.erase(it);
    ++observations_version_;
  }
  if (reference_ == kf) reference_ = observations_.empty() ? KeyFrameId() : observations_.begin()->first;
  return static_cast<int>(observations_.size());
}

std::optional<Observations> MapPoint::setBad(MapPointId replaced_by) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (bad_) return std::nullopt;
  bad_ = true;
  replaced_by_ = replaced_by;
  Observations observations;
  observations.swap(observations_);
  ++observations_version_;
  return observations;
}

features::Descriptor MapPoint::descriptor() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return descriptor_;
}
void MapPoint::setDescriptor(const features::Descriptor& descriptor) {
  std::lock_guard<std::mutex> lock(mutex_);
  descriptor_ = descriptor;
  descriptor_version_ = kNoVersion;
}
std::uint64_t MapPoint::versionedObservationsInto(Observations* out) const {
  std::lock_guard<std::mutex> lock(mutex_);
  out->assign(observations_.begin(), observations_.end());
  return observations_version_;
}
bool MapPoint::descriptorCurrent() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return descriptor_version_ == observations_version_;
}
void MapPoint::setDescriptor(const features::Descriptor& descriptor, std::uint64_t observations_version) {
  std::lock_guard<std::mutex> lock(mutex_);
  descriptor_ = descriptor;
  descriptor_version_ = observations_version;
}

int MapPoint::medianDescriptorIndex(const std::vector<features::Descriptor>& descriptors) {
  const std::size_t n = descriptors.size();
  if (n == 0) return -1;
  // Row-major n x n distances in one block (a point seen on every lap of a long run has tens).
  std::vector<int> distances(n * n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      distances[i * n + j] = distances[j * n + i] = features::hammingDistance(descriptors[i], descriptors[j]);
    }
  }
  int best_index = 0;
  int best_median = 257;
  const auto median_rank = static_cast<long>((n - 1) / 2);
  for (std::size_t i = 0; i < n; ++i) {
    const auto row = distances.begin() + static_cast<long>(i * n);
    // Lower median of the n distances (including 0 to itself), so two descriptors tie at 0.
    std::nth_element(row, row + median_rank, row + static_cast<long>(n));
    const int median = row[median_rank];
    if (median < best_median) {
      best_median = median;
      best_index = static_cast<int>(i);
    }
  }
  return best_index;
}

Vec3 MapPoint::normal_w() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return normal_w_;
}
double MapPoint::minDistance_m() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return min_distance_m_;
}
double MapPoint::maxDistance_m() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return max_distance_m_;
}
void MapPoint::setNormalAndDistances(const Vec3& normal_w, double min_distance_m, double max_distance_m) {
  std::lock_guard<std::mutex> lock(mutex_);
  normal_w_ = normal_w;
  min_distance_m_ = min_distance_m;
  max_distance_m_ = max_distance_m;
}

int MapPoint::predictScale(double distance_m, const std::vector<float>& scale_factors) const {
  LTLO_ASSERT(scale_factors.size() >= 2, "predictScale needs at least two pyramid levels");
  double max_distance_m = 0.0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    max_distance_m = max_distance_m_;
  }
  const double log_scale = std::log(static_cast<double>(scale_factors[1]));
  const int level = static_cast<int>(std::ceil(std::log(max_distance_m / distance_m) / log_scale));
  return std::clamp(level, 0, static_cast<int>(scale_factors.size()) - 1);
}

void MapPoint::increaseVisible(int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  num_visible_ += n;
}
void MapPoint::increaseFound(int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  num_found_ += n;
}
int MapPoint::numVisible() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return num_visible_;
}
int MapPoint::numFound() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return num_found_;
}
double MapPoint::foundRatio() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return num_visible_ > 0 ? static_cast<double>(num_found_) / num_visible_ : 1.0;
}

double MapPoint::beta() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return beta_;
}
void MapPoint::setBeta(double beta) {
  LTLO_ASSERT(beta >= 0.0 && beta <= 1.0, "beta of " << id_ << " = " << beta << ", expected [0, 1]");
  std::lock_guard<std::mutex> lock(mutex_);
  beta_ = beta;
}

bool MapPoint::isBad() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bad_;
}
MapPointId MapPoint::replacedBy() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return replaced_by_;
}

}  // namespace ltlo::map
