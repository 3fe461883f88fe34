#pragma once
/// The narrow restore API the atlas file reader needs (atlas_file.h): writes of state that the
/// public API only lets grow through the live system's own paths (container insertion with a given
/// id, the spanning tree and covisibility as saved, the tracking counters, the map table). Friend
/// of Atlas, Map, KeyFrame and MapPoint; used by src/map/*_io.cc and atlas_file.cc only, on objects
/// no other thread sees yet (a loaded atlas before it is returned).
#include <cstddef>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

#include "ltlo/map/atlas.h"
#include "ltlo/map/ids.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"
#include "ltlo/map/map_point.h"

namespace ltlo::map {

struct AtlasFileAccess {
  /// An Atlas without maps (the constructor's first map removed), for maps of given ids.
  static std::unique_ptr<Atlas> emptyAtlas(std::size_t num_words);
  /// Adds an empty map `id` sharing the atlas' id source; asserts the id is new.
  static Map& addMap(Atlas& atlas, MapId id);
  static IdSource& ids(Atlas& atlas);

  static bool createdKeyFrame(const Map& map);
  /// Inserts a restored keyframe / point under its own id, the origins and the created-keyframe
  /// flag as saved (createKeyFrame would issue a new id and make the first one an origin).
  static void insert(Map& map, std::shared_ptr<KeyFrame> kf);
  static void insert(Map& map, std::shared_ptr<MapPoint> point);
  static void setOrigins(Map& map, std::vector<KeyFrameId> origins, bool created_keyframe);

  /// The spanning tree and covisibility edges as saved (both ends are restored by the caller: every
  /// keyframe's own lists are written as they were).
  static void setTree(KeyFrame& kf, KeyFrameId parent, const std::vector<KeyFrameId>& children);
  static void setConnections(KeyFrame& kf, std::unordered_map<KeyFrameId, int> weights);

  /// Tracking counters as saved (the public API only increments them).
  static void setCounts(MapPoint& point, int num_visible, int num_found);

  // ---- the run state (run_state_io.h) ----
  /// Every map the atlas holds, the merged-away ones included, by id.
  static std::vector<MapId> allMapIds(const Atlas& atlas);
  /// The merges in the order they happened: (source, target).
  static std::vector<std::pair<MapId, MapId>> merges(const Atlas& atlas);
  /// Adds an empty map `id` that was merged into `target` (Atlas::resolve follows it; mapIds()
  /// leaves it out), appended to the merge order.
  static Map& addMergedMap(Atlas& atlas, MapId id, MapId target);
  static void setVersion(Map& map, std::uint64_t version);
  static void setAtRest(KeyFrame& kf, bool at_rest);
  /// A culled keyframe as a holder of it sees it: bad, with its culled parent and pose relative
  /// to it, its map, time and state (no image data: a culled keyframe's is read by nobody).
  static std::shared_ptr<KeyFrame> culledKeyFrame(KeyFrameId id, MapId map, const Frame& state);
  static void setCulledParent(KeyFrame& kf, std::shared_ptr<KeyFrame> parent, const SE3& T_parent_this);
};

}  // namespace ltlo::map
