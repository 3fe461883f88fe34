#pragma once
/// Atlas: the set of maps of a run (one active), and the keyframe database across them.
///
/// Lock order (never reversed, never a queue push while holding any of these):
///   Atlas::mutex_ -> Map::topology_mutex_ -> Map::mutex_ -> KeyFrame::mutex_ -> MapPoint::mutex_
/// KeyFrameDatabase::mutex_ is taken alone (never together with another lock). In practice only
/// Map::addObservation nests two of them (a KeyFrame's then a MapPoint's); every other method
/// takes one lock at a time and works on copies, so a caller may hold none of these while calling.
///
/// Threads: System owns the Atlas. Tracking reads the active map and creates a new one when lost;
/// local mapping inserts and culls; loop closing corrects, fuses and merges maps.
#include <cstddef>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/map/ids.h"
#include "ltlo/map/keyframe_database.h"
#include "ltlo/map/map.h"

namespace ltlo::map {

/// Restore-side entry points of the atlas file reader (src/map/atlas_file_access.h).
struct AtlasFileAccess;

/// Thread-safe; mutex_ guards the map table and the active id. Maps are never destroyed before
/// the Atlas (a merged map stays, empty), so a Map& obtained here stays valid for its lifetime.
class Atlas {
 public:
  /// `num_words` sizes the keyframe database (the vocabulary's numWords()). Starts with one map.
  explicit Atlas(std::size_t num_words);
  Atlas(const Atlas&) = delete;
  Atlas& operator=(const Atlas&) = delete;

  /// Starts a new empty map and makes it active (tracking lost); the previous maps are kept.
  Map& createNewMap();
  Map& activeMap();
  MapId activeMapId() const;
  void setActiveMap(MapId id);
  /// nullptr for an unknown id.
  Map* map(MapId id);
  /// The map `id` was merged into (following a chain of merges), `id` itself when it was never
  /// merged; an unknown id is returned as is.
  MapId resolve(MapId id) const;
  /// Maps still holding content (merged-away maps excluded), by id.
  std::vector<MapId> mapIds() const;
  std::size_t numMaps() const { return mapIds().size(); }

  /// Moves everything of map `source` into map `target`, expressing it in target's world frame:
  /// T_w_b <- T_target_source * T_w_b, v_w_b <- R * v_w_b, p_w <- T_target_source * p_w,
  /// normals rotated. The keyframes' mapId() becomes `target`; both maps' versions are bumped; if
  /// `source` was active, `target` becomes active. Spanning trees stay separate (the loop closer
  /// links them with a loop edge). Call with tracking and local mapping paused on `source`.
  void mergeMaps(MapId source, MapId target, const SE3& T_target_source);

  KeyFrameDatabase& keyFrameDatabase() { return database_; }
  const KeyFrameDatabase& keyFrameDatabase() const { return database_; }

 private:
  friend struct AtlasFileAccess;
  Map& createNewMapLocked();

  const std::shared_ptr<IdSource> ids_;
  KeyFrameDatabase database_;
  mutable std::mutex mutex_;  ///< guards maps_, merged_, merged_into_ and active_
  std::unordered_map<MapId, std::unique_ptr<Map>> maps_;
  std::vector<MapId> merged_;
  std::unordered_map<MapId, MapId> merged_into_;  ///< source -> target of each merge
  MapId active_;
};

}  // namespace ltlo::map
