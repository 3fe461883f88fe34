#pragma once
/// The sections of the atlas file (layout in atlas_file.h), one writer and one reader each, beside
/// the types they write: keyframe_io.cc (keyframes, IMU preintegration), map_point_io.cc (points),
/// map_io.cc (maps, graph), atlas_file.cc (header, build, imu). Private to ltlo_map.
#include <map>
#include <memory>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "ltlo/map/binary_io.h"
#include "ltlo/map/run_state_io.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/atlas.h"

namespace ltlo::map {

/// What saveAtlas writes: the maps not merged away, their live keyframes and points by id.
struct AtlasSnapshot {
  struct MapEntry {
    Map* map = nullptr;
    std::vector<std::shared_ptr<KeyFrame>> keyframes;
    std::vector<std::shared_ptr<MapPoint>> points;
  };
  MapId active;
  std::vector<MapEntry> maps;
  std::unordered_set<KeyFrameId> keyframe_ids;
  std::unordered_set<MapPointId> point_ids;

  bool saved(KeyFrameId id) const { return keyframe_ids.count(id) > 0; }
  bool saved(MapPointId id) const { return point_ids.count(id) > 0; }
};
AtlasSnapshot snapshotAtlas(Atlas& atlas);

/// The atlas being read, with every object by id (ids are unique across the atlas).
struct AtlasRestore {
  std::unique_ptr<Atlas> atlas;
  MapId active;
  std::map<MapId, Map*> maps;
  std::unordered_map<KeyFrameId, std::shared_ptr<KeyFrame>> keyframes;
  std::unordered_map<MapPointId, std::shared_ptr<MapPoint>> points;
};

void writeMapsSection(const AtlasSnapshot& snapshot, ByteWriter& out);
void readMapsSection(ByteReader& in, AtlasRestore& restore);
void writeKeyFramesSection(const AtlasSnapshot& snapshot, ByteWriter& out);
void readKeyFramesSection(ByteReader& in, AtlasRestore& restore);
void writePointsSection(const AtlasSnapshot& snapshot, ByteWriter& out);
void readPointsSection(ByteReader& in, AtlasRestore& restore);
void writeGraphSection(const AtlasSnapshot& snapshot, ByteWriter& out);
void readGraphSection(ByteReader& in, AtlasRestore& restore);

/// A map's origin (map_io.cc); its ids are history and need not exist.
void writeMapOrigin(const MapOrigin& origin, ByteWriter& out);
MapOrigin readMapOrigin(ByteReader& in);

/// A stored id: the raw value must not be the invalid marker unless `allow_invalid`.
MapId readMapId(ByteReader& in, const char* what);
/// The map `id` read from `in` must be one of the file's maps.
Map& readKnownMap(ByteReader& in, const AtlasRestore& restore, const char* what);
/// A keyframe id that must name a keyframe of the file (or be invalid when `allow_invalid`).
KeyFrameId readKnownKeyFrame(ByteReader& in, const AtlasRestore& restore, const char* what, bool allow_invalid);
MapPointId readKnownMapPoint(ByteReader& in, const AtlasRestore& restore, const char* what);
/// A link to an object that is not saved is written as the invalid id / left out (atlas_file.h).
inline std::uint64_t savedOrInvalid(const AtlasSnapshot& snapshot, KeyFrameId id) {
  return snapshot.saved(id) ? id.value : KeyFrameId::kInvalid;
}

}  // namespace ltlo::map
