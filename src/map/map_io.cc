// The maps and graph sections of the atlas file (atlas_file.h), the snapshot saveAtlas writes and
// the id checks shared by the section readers.
#include <algorithm>
#include <string>
#include <unordered_set>

#include "atlas_file_access.h"
#include "atlas_file_sections.h"

namespace ltlo::map {

namespace {

template <typename Id>
void writeIds(const std::vector<Id>& ids, ByteWriter& out) {
  out.u64(ids.size());
  for (const Id id : ids) out.u64(id.value);
}

std::vector<KeyFrameId> savedOnly(const AtlasSnapshot& snapshot, const std::vector<KeyFrameId>& ids) {
  std::vector<KeyFrameId> kept;
  for (const KeyFrameId id : ids) {
    if (snapshot.saved(id)) kept.push_back(id);
  }
  return kept;
}

std::vector<KeyFrameId> readKnownKeyFrames(ByteReader& in, const AtlasRestore& restore, const char* what) {
  const std::size_t n = in.count(what, 8);
  std::vector<KeyFrameId> ids;
  ids.reserve(n);
  for (std::size_t k = 0; k < n; ++k) ids.push_back(readKnownKeyFrame(in, restore, what, false));
  return ids;
}

void writeKeyFrameLinks(const KeyFrame& kf, const AtlasSnapshot& snapshot, ByteWriter& out) {
  out.u64(kf.id().value);
  out.u64(savedOrInvalid(snapshot, kf.previousKeyFrame()));
  out.u64(savedOrInvalid(snapshot, kf.nextKeyFrame()));
  out.u64(savedOrInvalid(snapshot, kf.parent()));
  writeIds(savedOnly(snapshot, kf.children()), out);
  std::vector<std::pair<KeyFrameId, int>> covisibles = kf.covisibles();
  covisibles.erase(std::remove_if(covisibles.begin(), covisibles.end(),
                                  [&](const std::pair<KeyFrameId, int>& edge) { return !snapshot.saved(edge.first); }),
                   covisibles.end());
  out.u64(covisibles.size());
  for (const auto& [other, weight] : covisibles) {
    out.u64(other.value);
    out.i32(weight);
  }
  writeIds(savedOnly(snapshot, kf.loopEdges()), out);
}

/// A weight is a count of shared points (at most a keyframe's keypoints); far below INT_MAX so sums
/// of weights cannot overflow.
constexpr std::int32_t kMaxWeight = 1 << 24;

void readKeyFrameLinks(ByteReader& in, AtlasRestore& restore, std::unordered_set<KeyFrameId>& seen) {
  const std::uint64_t offset = in.fileOffset();
  const KeyFrameId id = readKnownKeyFrame(in, restore, "graph keyframe", false);
  if (!seen.insert(id).second) in.failAt(offset, "keyframe links given twice", std::to_string(id.value));
  KeyFrame& kf = *restore.keyframes.at(id);
  kf.setPreviousKeyFrame(readKnownKeyFrame(in, restore, "previous keyframe", true));
  kf.setNextKeyFrame(readKnownKeyFrame(in, restore, "next keyframe", true));
  const std::uint64_t parent_offset = in.fileOffset();
  const KeyFrameId parent = readKnownKeyFrame(in, restore, "parent keyframe", true);
  if (parent == id) in.failAt(parent_offset, "keyframe is its own parent", std::to_string(id.value));
  AtlasFileAccess::setTree(kf, parent, readKnownKeyFrames(in, restore, "children"));
  const std::size_t num_edges = in.count("covisibility edges", 12);
  std::unordered_map<KeyFrameId, int> weights;
  for (std::size_t k = 0; k < num_edges; ++k) {
    const std::uint64_t edge_offset = in.fileOffset();
    const KeyFrameId other = readKnownKeyFrame(in, restore, "covisible keyframe", false);
    const int weight = in.i32InRange("covisibility weight", 1, kMaxWeight);
    if (other == id || !weights.emplace(other, weight).second) {
      in.failAt(edge_offset, "covisibility edge to itself or repeated", std::to_string(other.value));
    }
  }
  AtlasFileAccess::setConnections(kf, std::move(weights));
  for (const KeyFrameId other : readKnownKeyFrames(in, restore, "loop edges")) kf.addLoopEdge(other);
}

void writeMapLinks(const AtlasSnapshot::MapEntry& entry, const AtlasSnapshot& snapshot, ByteWriter& out) {
  const Map& map = *entry.map;
  out.u64(map.id().value);
  writeIds(savedOnly(snapshot, map.originKeyFrames()), out);
  const std::optional<MapOrigin> origin = map.origin();
  out.boolean(origin.has_value());
  if (origin) writeMapOrigin(*origin, out);
  std::vector<MapPointId> reference_points = map.referenceMapPoints();
  reference_points.erase(std::remove_if(reference_points.begin(), reference_points.end(),
                                        [&](MapPointId id) { return !snapshot.saved(id); }),
                         reference_points.end());
  writeIds(reference_points, out);
}

void readMapLinks(ByteReader& in, AtlasRestore& restore, std::unordered_set<MapId>& seen) {
  const std::uint64_t offset = in.fileOffset();
  Map& map = readKnownMap(in, restore, "graph map");
  if (!seen.insert(map.id()).second) in.failAt(offset, "map links given twice", std::to_string(map.id().value));
  AtlasFileAccess::setOrigins(map, readKnownKeyFrames(in, restore, "origin keyframes"),
                              AtlasFileAccess::createdKeyFrame(map));
  if (in.boolean("map has an origin")) map.setOrigin(readMapOrigin(in));
  const std::size_t num_references = in.count("reference map points", 8);
  std::vector<MapPointId> references;
  references.reserve(num_references);
  for (std::size_t k = 0; k < num_references; ++k)
    references.push_back(readKnownMapPoint(in, restore, "reference map point"));
  map.setReferenceMapPoints(std::move(references));
}

/// Walks from every keyframe up its parents: a cycle would make the live system's tree walks
/// (loop correction, culling) loop for ever. Each keyframe is walked once (O(keyframes)).
void checkTreeIsAcyclic(const ByteReader& in, const AtlasRestore& restore, std::uint64_t offset) {
  std::unordered_set<KeyFrameId> rooted;  // keyframes whose parent chain ends at a root
  for (const auto& [start, kf] : restore.keyframes) {
    std::unordered_set<KeyFrameId> path;
    KeyFrameId id = start;
    while (id.valid() && rooted.count(id) == 0) {
      if (!path.insert(id).second)
        in.failAt(offset, "the spanning tree has a cycle through keyframe", std::to_string(id.value));
      id = restore.keyframes.at(id)->parent();
    }
    rooted.insert(path.begin(), path.end());
  }
}

}  // namespace

void writeMapOrigin(const MapOrigin& origin, ByteWriter& out) {
  out.u64(origin.parent.value);
  out.f64(origin.sigma_position_m);
  out.f64(origin.sigma_rotation_rad);
  out.f64(origin.t_s);
  out.u64(origin.parent_keyframe.value);
  out.u64(origin.first_keyframe.value);
  out.boolean(origin.imu_across != nullptr);
  if (origin.imu_across) writePreintegration(*origin.imu_across, out);
  out.se3(origin.T_w_b_parent_keyframe);
}

/// The origin's ids are history (the map and keyframes the map started from; they may have been
/// merged away or culled since), so they are not required to exist.
MapOrigin readMapOrigin(ByteReader& in) {
  MapOrigin origin;
  origin.parent = MapId(in.u64("origin parent map"));
  origin.sigma_position_m = in.finiteF64("origin position sigma");
  origin.sigma_rotation_rad = in.finiteF64("origin rotation sigma");
  origin.t_s = in.finiteF64("origin time");
  origin.parent_keyframe = KeyFrameId(in.u64("origin parent keyframe"));
  origin.first_keyframe = KeyFrameId(in.u64("origin first keyframe"));
  if (in.boolean("origin has imu_across"))
    origin.imu_across = std::make_shared<imu::Preintegrated>(readPreintegration(in));
  origin.T_w_b_parent_keyframe = in.se3("origin T_w_b_parent_keyframe");
  return origin;
}

AtlasSnapshot snapshotAtlas(Atlas& atlas) {
  AtlasSnapshot snapshot;
  snapshot.active = atlas.activeMapId();
  for (const MapId id : atlas.mapIds()) {
    AtlasSnapshot::MapEntry entry;
    entry.map = atlas.map(id);
    for (std::shared_ptr<KeyFrame>& kf : entry.map->keyFrames()) {
      if (kf->isBad()) continue;
      snapshot.keyframe_ids.insert(kf->id());
      entry.keyframes.push_back(std::move(kf));
    }
    for (std::shared_ptr<MapPoint>& point : entry.map->mapPoints()) {
      if (point->isBad()) continue;
      snapshot.point_ids.insert(point->id());
      entry.points.push_back(std::move(point));
    }
    snapshot.maps.push_back(std::move(entry));
  }
  return snapshot;
}

MapId readMapId(ByteReader& in, const char* what) {
  const std::uint64_t offset = in.fileOffset();
  const MapId id(in.u64(what));
  if (!id.valid()) in.failAt(offset, std::string(what) + " is the invalid id", std::to_string(id.value));
  return id;
}

Map& readKnownMap(ByteReader& in, const AtlasRestore& restore, const char* what) {
  const std::uint64_t offset = in.fileOffset();
  const MapId id(in.u64(what));
  const auto it = restore.maps.find(id);
  if (it == restore.maps.end())
    in.failAt(offset, std::string(what) + " is not a map of the file", std::to_string(id.value));
  return *it->second;
}

KeyFrameId readKnownKeyFrame(ByteReader& in, const AtlasRestore& restore, const char* what, bool allow_invalid) {
  const std::uint64_t offset = in.fileOffset();
  const KeyFrameId id(in.u64(what));
  if (allow_invalid && !id.valid()) return id;
  if (restore.keyframes.count(id) == 0) {
    in.failAt(offset, std::string(what) + " is not a keyframe of the file", std::to_string(id.value));
  }
  return id;
}

MapPointId readKnownMapPoint(ByteReader& in, const AtlasRestore& restore, const char* what) {
  const std::uint64_t offset = in.fileOffset();
  const MapPointId id(in.u64(what));
  if (restore.points.count(id) == 0) {
    in.failAt(offset, std::string(what) + " is not a map point of the file", std::to_string(id.value));
  }
  return id;
}

void writeMapsSection(const AtlasSnapshot& snapshot, ByteWriter& out) {
  out.u64(snapshot.active.value);
  out.u64(snapshot.maps.size());
  for (const AtlasSnapshot::MapEntry& entry : snapshot.maps) {
    out.u64(entry.map->id().value);
    out.boolean(AtlasFileAccess::createdKeyFrame(*entry.map));
  }
}

void readMapsSection(ByteReader& in, AtlasRestore& restore) {
  const std::uint64_t active_offset = in.fileOffset();
  restore.active = readMapId(in, "active map");
  const std::uint64_t count_offset = in.fileOffset();
  const std::size_t n = in.count("maps", 9);
  if (n == 0) in.failAt(count_offset, "an atlas has at least one map", "0");
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint64_t offset = in.fileOffset();
    const MapId id = readMapId(in, "map id");
    if (restore.maps.count(id) > 0) in.failAt(offset, "map id repeated", std::to_string(id.value));
    Map& map = AtlasFileAccess::addMap(*restore.atlas, id);
    AtlasFileAccess::setOrigins(map, {}, in.boolean("map created a keyframe"));
    restore.maps.emplace(id, &map);
  }
  if (restore.maps.count(restore.active) == 0) {
    in.failAt(active_offset, "active map is not a map of the file", std::to_string(restore.active.value));
  }
  restore.atlas->setActiveMap(restore.active);
  in.expectEnd();
}

void writeGraphSection(const AtlasSnapshot& snapshot, ByteWriter& out) {
  out.u64(snapshot.keyframe_ids.size());
  for (const AtlasSnapshot::MapEntry& entry : snapshot.maps) {
    for (const std::shared_ptr<KeyFrame>& kf : entry.keyframes) writeKeyFrameLinks(*kf, snapshot, out);
  }
  out.u64(snapshot.maps.size());
  for (const AtlasSnapshot::MapEntry& entry : snapshot.maps) writeMapLinks(entry, snapshot, out);
}

void readGraphSection(ByteReader& in, AtlasRestore& restore) {
  const std::uint64_t offset = in.fileOffset();
  const std::size_t num_keyframes = in.count("graph keyframes", 8 * 4 + 8 * 3);
  if (num_keyframes != restore.keyframes.size()) {
    in.failAt(offset, "links for " + std::to_string(restore.keyframes.size()) + " keyframes",
              std::to_string(num_keyframes));
  }
  std::unordered_set<KeyFrameId> seen_keyframes;
  for (std::size_t k = 0; k < num_keyframes; ++k) readKeyFrameLinks(in, restore, seen_keyframes);
  const std::uint64_t maps_offset = in.fileOffset();
  const std::size_t num_maps = in.count("graph maps", 8 + 8 + 1 + 8);
  if (num_maps != restore.maps.size()) {
    in.failAt(maps_offset, "links for " + std::to_string(restore.maps.size()) + " maps", std::to_string(num_maps));
  }
  std::unordered_set<MapId> seen_maps;
  for (std::size_t k = 0; k < num_maps; ++k) readMapLinks(in, restore, seen_maps);
  in.expectEnd();
  checkTreeIsAcyclic(in, restore, offset);
}

}  // namespace ltlo::map
