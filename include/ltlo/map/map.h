#pragma once
/// Map: one connected reconstruction. Owns its keyframes and map points (shared_ptr in id-keyed
/// containers) and keeps the links between them (observations, covisibility, spanning tree)
/// consistent on both ends.
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <vector>

#include "ltlo/map/frame.h"
#include "ltlo/map/ids.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/map_point.h"

namespace ltlo::map {

/// Restore-side entry points of the atlas file reader (src/map/atlas_file_access.h).
struct AtlasFileAccess;

/// Where a map started after tracking was lost with the IMU initialised: at the IMU-predicted pose
/// in the world of `parent`, so both share the gravity-aligned world frame up to the dead
/// reckoning's error at the start (the loop closer's rejoin searches within it, Loop.Rejoin).
struct MapOrigin {
  MapId parent;
  double sigma_position_m = 0.0;    ///< of the first keyframe's position in the parent's world
  double sigma_rotation_rad = 0.0;  ///< of its rotation
  double t_s = 0.0;                 ///< time of the first frame
  /// The IMU across the loss, when its chain was unbroken: the parent's last keyframe, the new map's
  /// first keyframe and the preintegration from the one to the other. Once both lie in one map
  /// (rejoin or merge), the first keyframe's inertial link (map_merger.h, bridgeOrigins).
  KeyFrameId parent_keyframe;
  KeyFrameId first_keyframe;
  std::shared_ptr<const imu::Preintegrated> imu_across;
  /// The parent keyframe's body pose when the map started (the map's world is the parent's as it
  /// was then; corrections of the parent since move it with that keyframe).
  SE3 T_w_b_parent_keyframe;
  /// The first keyframe's dead-reckoned velocity (m/s, in the parent's world) and the standard
  /// deviation of the prediction it came from (m/s; 0: unknown), for
  /// LocalMapping.GaugeVelocityPrior. Not written to atlas files (a loaded map's gauge velocity then
  /// has no prior).
  Vec3 v_w_b_dead_reckoned = Vec3::Zero();
  double sigma_velocity_m_s = 0.0;
};

/// Thread-safe. mutex_ guards the containers only and is never held while a KeyFrame or MapPoint
/// method runs; topology_mutex_ serialises covisibility updates, erasures and fusions (taken
/// first, see atlas.h).
/// Touched by every thread: tracking (snapshots, reference points), local mapping (insertion,
/// culling), loop closing (correction, fusion) and the Atlas (merging).
class Map {
 public:
  /// A map drawing ids from `ids` (shared by all maps of an Atlas so ids stay unique on merge).
  Map(MapId id, std::shared_ptr<IdSource> ids);
  /// A stand-alone map with its own id source.
  Map();
  Map(const Map&) = delete;
  Map& operator=(const Map&) = delete;

  MapId id() const { return id_; }

  /// Promotes `frame` (with a pose) to a keyframe with a new id and inserts it. The first keyframe
  /// created in this map becomes an origin keyframe (spanning-tree root, never culled); a merge
  /// adds the other map's origins.
  std::shared_ptr<KeyFrame> createKeyFrame(const Frame& frame);
  /// A new map point at p_w (m, world) with a new id, inserted; observations are added separately.
  std::shared_ptr<MapPoint> createMapPoint(const Vec3& p_w, KeyFrameId reference);

  /// nullptr when the id is not (or no longer) in this map.
  std::shared_ptr<KeyFrame> keyFrame(KeyFrameId id) const;
  std::shared_ptr<MapPoint> mapPoint(MapPointId id) const;
  /// mapPoint() of every id under one lock (a keyframe's points at once: the lock is shared with
  /// tracking's per-frame searches): (*out)[i] for ids[i], nullptr for an invalid or absent id.
  void mapPointsInto(const std::vector<MapPointId>& ids, std::vector<std::shared_ptr<MapPoint>>* out) const;
  /// Snapshots copied under the lock, ordered by id.
  std::vector<std::shared_ptr<KeyFrame>> keyFrames() const;
  std::vector<std::shared_ptr<MapPoint>> mapPoints() const;
  std::size_t numKeyFrames() const;
  std::size_t numMapPoints() const;
  /// The first keyframe of this map and of every map merged into it: never culled, roots of the
  /// spanning tree.
  std::vector<KeyFrameId> originKeyFrames() const;
  /// The keyframe the map's BAs hold as their gauge: the map's own first keyframe (invalid before
  /// it has one). The origins of maps merged into it are not held: a merge places them by the
  /// seam's alignment, which the BAs must be free to correct.
  KeyFrameId gaugeKeyFrame() const;
  /// Makes `id` (a keyframe of this map) the gauge and an origin (never culled) in place of the
  /// gauge before, which becomes an ordinary keyframe: an occluded start relocalised on `id`, and the
  /// map grows on in its world (Tracking.StartRecoveryGauge). Returns the previous gauge.
  KeyFrameId moveGaugeTo(KeyFrameId id);

  /// Links keypoint `keypoint_index` of `kf` to `point` on both ends. Returns false (and links
  /// nothing) when either is bad, the keypoint holds another point, or `point` is already seen at
  /// another keypoint of `kf` (erase that link first). Takes KeyFrame::mutex_ then MapPoint::mutex_.
  bool addObservation(KeyFrame& kf, int keypoint_index, MapPoint& point);
  /// Unlinks keypoint `keypoint_index` of `kf` from its map point on both ends (no-op if none).
  void eraseObservation(KeyFrame& kf, int keypoint_index);

  /// Recomputes the covisibility edges of `kf` from the points it shares with other keyframes
  /// (weights >= kMinCovisibilityWeight, or the single strongest edge), updates the other ends, and
  /// gives `kf` a spanning-tree parent (its best older covisible) if it has none and is not an origin.
  void updateConnections(KeyFrame& kf);
  /// Representative descriptor of `point` from its observations (MapPoint::medianDescriptorIndex).
  void updateDescriptor(MapPoint& point);
  /// Mean viewing direction and scale-invariance distances of `point` from its observations.
  void updateNormalAndDistances(MapPoint& point);

  /// Culls a keyframe: marks it bad, removes its covisibility edges and observations, re-parents its
  /// children (each to the covisible among its parent and re-parented siblings sharing the most
  /// points, else to its parent), bridges the IMU chain (merged preintegration) and removes it from
  /// the map. Holders of its shared_ptr keep a valid (bad) object. Points left without observations
  /// are erased too. Returns false if the id is unknown, already bad, or an origin keyframe.
  /// With `imu_link` kCut the chain is not bridged: the next keyframe loses its preintegration (a
  /// gap in the chain; culling of old keyframes whose neighbours are too far apart in time to merge).
  enum class ImuLink { kMerge, kCut };
  bool eraseKeyFrame(KeyFrameId id, ImuLink imu_link = ImuLink::kMerge);
  /// Culls a map point: marks it bad, unlinks it from its keyframes, removes it from the map.
  bool eraseMapPoint(MapPointId id);
  /// Fusion: moves the observations of `old_id` to `replacement` (where the keyframe has no other
  /// link to it), marks `old_id` bad with replacedBy() = replacement and removes it.
  bool replaceMapPoint(MapPointId old_id, MapPointId replacement);

  /// Points tracking projects into the current frame (set by local mapping / tracking).
  void setReferenceMapPoints(std::vector<MapPointId> points);
  std::vector<MapPointId> referenceMapPoints() const;

  /// Set by tracking when it starts this map at an IMU prediction (see MapOrigin).
  void setOrigin(const MapOrigin& origin);
  std::optional<MapOrigin> origin() const;

  /// Bumped on changes that invalidate what tracking holds (loop correction, merge).
  std::uint64_t version() const { return version_.load(); }
  void bumpVersion() { version_.fetch_add(1); }

 private:
  friend class Atlas;
  friend struct AtlasFileAccess;
  /// Everything a merge moves from one map into another.
  struct Content {
    std::unordered_map<KeyFrameId, std::shared_ptr<KeyFrame>> keyframes;
    std::unordered_map<MapPointId, std::shared_ptr<MapPoint>> points;
    std::vector<KeyFrameId> origins;
  };
  Content takeContent();
  void addContent(Content content);
  bool isOrigin(KeyFrameId id) const;
  void eraseMapPointUnserialised(MapPointId id);
  /// keyFrame() of every observer under one lock ((*out)[i] for observations[i]; nullptr if absent).
  void observersInto(const Observations& observations, std::vector<std::shared_ptr<KeyFrame>>* out) const;

  const MapId id_;
  const std::shared_ptr<IdSource> ids_;
  std::atomic<std::uint64_t> version_{0};

  mutable std::mutex topology_mutex_;  ///< serialises updateConnections/erase/replace (stable graph)
  mutable std::mutex mutex_;           ///< guards the containers below, nothing else
  std::unordered_map<KeyFrameId, std::shared_ptr<KeyFrame>> keyframes_;
  std::unordered_map<MapPointId, std::shared_ptr<MapPoint>> points_;
  std::vector<KeyFrameId> origins_;
  std::optional<MapOrigin> origin_;
  bool created_keyframe_ = false;  ///< createKeyFrame() was called (its first keyframe is an origin)
  std::vector<MapPointId> reference_points_;
};

}  // namespace ltlo::map
