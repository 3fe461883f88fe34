#pragma once
/// MapPoint: a 3-D landmark observed by keyframes. Shared by tracking (reads, found/visible
/// counters), local mapping (creation, fusion, culling, BA) and loop closing (fusion, correction).
#include <cstdint>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/features/orb_extractor.h"
#include "ltlo/map/ids.h"

namespace ltlo::map {

/// Restore-side entry points of the atlas file reader (src/map/atlas_file_access.h).
struct AtlasFileAccess;

/// Where a map point is expected to be found again (ORB-SLAM's visibility test, used by tracking's
/// local-map search, local mapping's fusion and window, and loop closing's seam fusion): from within
/// [kMinDistanceFactor, kMaxDistanceFactor] x its distance range (the scale invariance of its
/// descriptor, widened) and no more than 60 degrees off its mean viewing direction (kMinViewingCos);
/// outside, its descriptor would not be found in the image either.
inline constexpr double kMinDistanceFactor = 0.8;
inline constexpr double kMaxDistanceFactor = 1.2;
inline constexpr double kMinViewingCos = 0.5;

/// A point's observations: (observing keyframe, keypoint index) pairs sorted by keyframe id, one
/// per keyframe. A flat list: copied with one allocation (or none into a reused buffer), where a
/// tree would allocate a node per observer, on every lap of a long run (issue 32).
using Observations = std::vector<std::pair<KeyFrameId, int>>;

/// Thread-safe: every member is guarded by the point's own mutex_ and returned as a copy; the
/// innermost lock of the order in atlas.h (MapPoint methods take no other lock).
class MapPoint {
 public:
  /// A point at p_w (m, world) first seen in `reference` (its keyframe for normal and scale).
  MapPoint(MapPointId id, const Vec3& p_w, KeyFrameId reference);
  MapPoint(const MapPoint&) = delete;
  MapPoint& operator=(const MapPoint&) = delete;

  MapPointId id() const { return id_; }
  Vec3 p_w() const;
  void setPosition(const Vec3& p_w);

  /// Observing keyframes -> keypoint index, ordered by keyframe id (written through Map).
  Observations observations() const;
  /// The same into *out (its capacity reused: the hot paths of local mapping call it per point).
  void observationsInto(Observations* out) const;
  int numObservations() const;
  /// Keypoint index of this point in `kf`, if observed there.
  std::optional<int> indexIn(KeyFrameId kf) const;
  KeyFrameId referenceKeyFrame() const;

  /// Representative descriptor: the observation with the least median distance to the others.
  features::Descriptor descriptor() const;
  /// Sets a descriptor not derived from the observations (a new or loaded point): the next
  /// Map::updateDescriptor recomputes it.
  void setDescriptor(const features::Descriptor& descriptor);
  /// The observations with their version: a count of the changes to them (links added, moved or
  /// erased), so a descriptor derived from them can tell it is still current.
  std::uint64_t versionedObservationsInto(Observations* out) const;
  /// Whether the descriptor was derived from the observations as they are now.
  bool descriptorCurrent() const;
  /// Sets the descriptor derived from the observations at `observations_version`.
  void setDescriptor(const features::Descriptor& descriptor, std::uint64_t observations_version);
  /// Index of the descriptor with the smallest median Hamming distance to all the others (ties:
  /// lowest index); -1 for an empty list.
  static int medianDescriptorIndex(const std::vector<features::Descriptor>& descriptors);

  /// Mean viewing direction (unit, world) and the distance range (m) over which the point's
  /// descriptor is expected to be detected (scale invariance, as in ORB-SLAM).
  Vec3 normal_w() const;
  double minDistance_m() const;
  double maxDistance_m() const;
  void setNormalAndDistances(const Vec3& normal_w, double min_distance_m, double max_distance_m);
  /// Pyramid level at which a point seen at distance_m is expected, clamped to the levels of
  /// `scale_factors` (OrbExtractor::scaleFactors()).
  int predictScale(double distance_m, const std::vector<float>& scale_factors) const;

  /// Tracking statistics: frames in whose view it fell, frames where it was matched.
  void increaseVisible(int n = 1);
  void increaseFound(int n = 1);
  int numVisible() const;
  int numFound() const;
  /// found / visible (1 before it was ever visible).
  double foundRatio() const;

  /// Static score beta in [0, 1] (DESIGN.md; 1 until the segmentation issue estimates it).
  double beta() const;
  void setBeta(double beta);

  bool isBad() const;
  /// The point that replaced this one in a fusion (invalid when not replaced).
  MapPointId replacedBy() const;

 private:
  friend class Map;
  friend struct AtlasFileAccess;
  bool addObservation(KeyFrameId kf, int keypoint_index);  ///< false on a bad point
  /// Returns the number of remaining observations; moves the reference keyframe if it was `kf`.
  int eraseObservation(KeyFrameId kf);
  /// Marks bad and hands back the observations it had (cleared here).
  std::optional<Observations> setBad(MapPointId replaced_by);
  /// The keypoint index in `kf` (-1: none), and adding or replacing it; the caller holds mutex_.
  int indexInLocked(KeyFrameId kf) const;
  void setObservationLocked(KeyFrameId kf, int keypoint_index);

  const MapPointId id_;
  mutable std::mutex mutex_;  ///< guards every member below
  Vec3 p_w_;
  Observations observations_;
  KeyFrameId reference_;
  features::Descriptor descriptor_{};
  static constexpr std::uint64_t kNoVersion = ~std::uint64_t{0};
  std::uint64_t observations_version_ = 0;  ///< changes to observations_ so far
  /// observations_version_ the descriptor was derived at (kNoVersion: none, or set otherwise)
  std::uint64_t descriptor_version_ = kNoVersion;
  Vec3 normal_w_ = Vec3::Zero();
  double min_distance_m_ = 0.0;
  double max_distance_m_ = 0.0;
  int num_visible_ = 1;
  int num_found_ = 1;
  double beta_ = 1.0;
  bool bad_ = false;
  MapPointId replaced_by_;
};

}  // namespace ltlo::map
