// The atlas's part of the run state (run_state_io.h): header, id counters, map versions, the maps
// merged away, the keyframe database's order, keyframe flags and the culled keyframes the stages
// hold; the keyframe references of the stages' parts.
#include "ltlo/map/run_state_io.h"

#include <algorithm>
#include <string>

#include "atlas_file_access.h"
#include "atlas_file_sections.h"
#include "record_io.h"

namespace ltlo::map {

namespace {

constexpr std::size_t kIdBytes = 8;

/// Every keyframe of the atlas's maps by id.
std::unordered_map<KeyFrameId, std::shared_ptr<KeyFrame>> atlasKeyFrames(Atlas& atlas) {
  std::unordered_map<KeyFrameId, std::shared_ptr<KeyFrame>> keyframes;
  for (const MapId id : atlas.mapIds()) {
    for (std::shared_ptr<KeyFrame>& kf : atlas.map(id)->keyFrames()) keyframes.emplace(kf->id(), std::move(kf));
  }
  return keyframes;
}

void writeKeyFrameIds(const std::vector<KeyFrameId>& ids, ByteWriter& out) {
  out.u64(ids.size());
  for (const KeyFrameId id : ids) out.u64(id.value);
}

/// Ids that must name keyframes of the atlas, each once.
std::vector<KeyFrameId> readAtlasKeyFrameIds(ByteReader& in, const char* what,
                                             const std::unordered_map<KeyFrameId, std::shared_ptr<KeyFrame>>& known) {
  const std::size_t n = in.count(what, kIdBytes);
  std::vector<KeyFrameId> ids;
  ids.reserve(n);
  std::unordered_set<KeyFrameId> seen;
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint64_t offset = in.fileOffset();
    const KeyFrameId id(in.u64(what));
    if (known.count(id) == 0)
      in.failAt(offset, std::string(what) + " is not a keyframe of the file", std::to_string(id.value));
    if (!seen.insert(id).second) in.failAt(offset, std::string(what) + " given twice", std::to_string(id.value));
    ids.push_back(id);
  }
  return ids;
}

void writeCulledKeyFrame(const KeyFrame& kf, ByteWriter& out) {
  out.u64(kf.id().value);
  out.u64(kf.mapId().value);
  const std::shared_ptr<KeyFrame> parent = kf.culledParent();
  out.u64(parent ? parent->id().value : KeyFrameId::kInvalid);
  out.se3(kf.T_parent_this());
  out.f64(kf.t_s());
  writeCamera(kf.camera(), out);
  out.se3(kf.T_b_c());
  out.se3(kf.T_w_b());
  out.vec3(kf.v_w_b());
  writeBias(kf.bias(), out);
}

AtlasRunState::CulledKeyFrame readCulledKeyFrame(ByteReader& in) {
  AtlasRunState::CulledKeyFrame culled;
  const std::uint64_t offset = in.fileOffset();
  culled.id = KeyFrameId(in.u64("culled keyframe id"));
  if (!culled.id.valid()) in.failAt(offset, "culled keyframe id is the invalid id", std::to_string(culled.id.value));
  culled.map = MapId(in.u64("culled keyframe map"));
  culled.culled_parent = KeyFrameId(in.u64("culled keyframe parent"));
  culled.T_parent_this = in.se3("culled keyframe T_parent_this");
  const double t_s = in.finiteF64("culled keyframe time");
  const PinholeCamera camera = readCamera(in);
  const SE3 T_b_c = in.se3("culled keyframe T_b_c");
  Frame state(t_s, camera, T_b_c, features::OrbFeatures{}, {}, {1.0f});
  state.setPose_T_w_b(in.se3("culled keyframe T_w_b"));
  state.setVelocity(in.vec3("culled keyframe velocity"));
  state.setBias(readBias(in, "culled keyframe bias"));
  culled.state = std::move(state);
  return culled;
}

}  // namespace

// ---- keyframe references ----

void KeyFrameRefs::write(const std::shared_ptr<const KeyFrame>& kf, ByteWriter& out) {
  out.u64(kf ? kf->id().value : KeyFrameId::kInvalid);
  // The culled chain up to a live keyframe (map::latestPose_T_w_b walks it).
  for (std::shared_ptr<const KeyFrame> link = kf; link && link->isBad(); link = link->culledParent()) {
    if (!seen_.insert(link->id()).second) break;
    culled_.push_back(link);
  }
}

std::shared_ptr<KeyFrame> RunKeyFrames::read(ByteReader& in, const char* what) const {
  const std::uint64_t offset = in.fileOffset();
  const KeyFrameId id(in.u64(what));
  if (!id.valid()) return nullptr;
  std::shared_ptr<KeyFrame> kf = find(id);
  if (!kf)
    in.failAt(offset, std::string(what) + " is neither a keyframe of the file nor a culled one",
              std::to_string(id.value));
  return kf;
}

std::shared_ptr<KeyFrame> RunKeyFrames::find(KeyFrameId id) const {
  const auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : it->second;
}

void RunKeyFrames::add(std::shared_ptr<KeyFrame> kf) {
  const KeyFrameId id = kf->id();
  keyframes_[id] = std::move(kf);
}

// ---- the atlas's part ----

void writeAtlasRunState(Atlas& atlas, const RunStateHeader& header, const KeyFrameRefs& refs, ByteWriter& out) {
  out.u64(header.next_frame_index);
  out.f64(header.last_frame_t_s);
  const IdSource::Counters ids = AtlasFileAccess::ids(atlas).counters();
  out.u64(ids.keyframe);
  out.u64(ids.point);
  out.u64(ids.map);
  const std::vector<MapId> saved = atlas.mapIds();
  out.u64(saved.size());
  for (const MapId id : saved) {
    out.u64(id.value);
    out.u64(atlas.map(id)->version());
  }
  const std::vector<std::pair<MapId, MapId>> merges = AtlasFileAccess::merges(atlas);
  out.u64(merges.size());
  for (const auto& [source, target] : merges) {
    const Map& map = *atlas.map(source);
    out.u64(source.value);
    out.u64(target.value);
    out.u64(map.version());
    out.boolean(AtlasFileAccess::createdKeyFrame(map));
    const std::optional<MapOrigin> origin = map.origin();
    out.boolean(origin.has_value());
    if (origin) writeMapOrigin(*origin, out);
  }
  writeKeyFrameIds(atlas.keyFrameDatabase().keyFrameIdsInOrder(), out);
  std::vector<KeyFrameId> anchors, at_rest;
  for (const MapId id : saved) {
    for (const std::shared_ptr<KeyFrame>& kf : atlas.map(id)->keyFrames()) {
      if (kf->isBad()) continue;
      if (kf->isAnchor()) anchors.push_back(kf->id());
      if (kf->atRest()) at_rest.push_back(kf->id());
    }
  }
  writeKeyFrameIds(anchors, out);
  writeKeyFrameIds(at_rest, out);
  out.u64(refs.culled().size());
  for (const std::shared_ptr<const KeyFrame>& kf : refs.culled()) writeCulledKeyFrame(*kf, out);
}

AtlasRunState readAtlasRunState(ByteReader& in, Atlas& atlas) {
  AtlasRunState state;
  state.header.next_frame_index = in.u64("next frame index");
  state.header.last_frame_t_s = in.finiteF64("last frame time");
  const std::uint64_t ids_offset = in.fileOffset();
  state.next_ids.keyframe = in.u64("next keyframe id");
  state.next_ids.point = in.u64("next map point id");
  state.next_ids.map = in.u64("next map id");
  const std::unordered_map<KeyFrameId, std::shared_ptr<KeyFrame>> keyframes = atlasKeyFrames(atlas);

  // Versions of the file's maps, each once.
  const std::vector<MapId> saved = atlas.mapIds();
  const std::uint64_t versions_offset = in.fileOffset();
  const std::size_t num_versions = in.count("map versions", 16);
  if (num_versions != saved.size()) {
    in.failAt(versions_offset, "versions for " + std::to_string(saved.size()) + " maps", std::to_string(num_versions));
  }
  for (std::size_t k = 0; k < num_versions; ++k) {
    const std::uint64_t offset = in.fileOffset();
    const MapId id(in.u64("versioned map"));
    if (id != saved[k]) in.failAt(offset, "map versions out of the file's map order", std::to_string(id.value));
    state.map_versions.emplace_back(id, in.u64("map version"));
  }
  // The maps merged away: new ids, targets among all maps.
  const std::size_t num_merged = in.count("merged maps", 8 + 8 + 8 + 1 + 1);
  std::unordered_set<MapId> all_maps(saved.begin(), saved.end());
  std::vector<std::uint64_t> target_offsets;
  for (std::size_t k = 0; k < num_merged; ++k) {
    AtlasRunState::MergedMap merged;
    const std::uint64_t offset = in.fileOffset();
    merged.id = readMapId(in, "merged map");
    if (!all_maps.insert(merged.id).second)
      in.failAt(offset, "merged map id repeated", std::to_string(merged.id.value));
    target_offsets.push_back(in.fileOffset());
    merged.target = readMapId(in, "merge target");
    merged.version = in.u64("merged map version");
    merged.created_keyframe = in.boolean("merged map created a keyframe");
    if (in.boolean("merged map has an origin")) merged.origin = readMapOrigin(in);
    state.merged.push_back(std::move(merged));
  }
  for (std::size_t k = 0; k < state.merged.size(); ++k) {
    const AtlasRunState::MergedMap& merged = state.merged[k];
    if (all_maps.count(merged.target) == 0 || merged.target == merged.id) {
      in.failAt(target_offsets[k], "merge target is not another map of the file", std::to_string(merged.target.value));
    }
  }
  // A merge chain must end in a map of the file (Atlas::resolve follows it).
  std::unordered_map<MapId, MapId> into;
  for (const AtlasRunState::MergedMap& merged : state.merged) into[merged.id] = merged.target;
  for (std::size_t k = 0; k < state.merged.size(); ++k) {
    MapId id = state.merged[k].id;
    for (std::size_t steps = 0; into.count(id) > 0; ++steps) {
      if (steps > state.merged.size())
        in.failAt(target_offsets[k], "merge targets form a cycle", std::to_string(id.value));
      id = into.at(id);
    }
  }
  state.database = readAtlasKeyFrameIds(in, "database keyframe", keyframes);
  state.anchors = readAtlasKeyFrameIds(in, "anchor keyframe", keyframes);
  state.at_rest = readAtlasKeyFrameIds(in, "keyframe at rest", keyframes);

  // Culled keyframes: ids new to the file, parents among the file's keyframes or each other, chains
  // ending in a keyframe of the file or none (latestPose_T_w_b must end).
  const std::size_t num_culled = in.count("culled keyframes", 8 * 3 + 56 * 3 + 8 + 40 + 24 + 48);
  std::unordered_map<KeyFrameId, KeyFrameId> parent_of;
  std::vector<std::uint64_t> offsets;
  for (std::size_t k = 0; k < num_culled; ++k) {
    offsets.push_back(in.fileOffset());
    AtlasRunState::CulledKeyFrame culled = readCulledKeyFrame(in);
    if (keyframes.count(culled.id) > 0 || !parent_of.emplace(culled.id, culled.culled_parent).second) {
      in.failAt(offsets.back(), "culled keyframe id repeated or of a live keyframe", std::to_string(culled.id.value));
    }
    if (all_maps.count(culled.map) == 0) {
      in.failAt(offsets.back(), "culled keyframe's map is not a map of the file", std::to_string(culled.map.value));
    }
    state.culled.push_back(std::move(culled));
  }
  for (std::size_t k = 0; k < state.culled.size(); ++k) {
    KeyFrameId id = state.culled[k].id;
    for (std::size_t steps = 0; parent_of.count(id) > 0; ++steps) {
      if (steps > state.culled.size())
        in.failAt(offsets[k], "culled keyframes' parents form a cycle", std::to_string(id.value));
      id = parent_of.at(id);
    }
    if (id.valid() && keyframes.count(id) == 0) {
      in.failAt(offsets[k], "culled keyframe's parent is not a keyframe of the file", std::to_string(id.value));
    }
  }
  // Every id of the file below the counters: new objects must not collide with loaded ones.
  std::uint64_t max_keyframe = 0, max_map = 0, max_point = 0;
  bool any_keyframe = false, any_point = false;
  for (const auto& [id, kf] : keyframes) max_keyframe = std::max(max_keyframe, id.value), any_keyframe = true;
  for (const AtlasRunState::CulledKeyFrame& culled : state.culled)
    max_keyframe = std::max(max_keyframe, culled.id.value), any_keyframe = true;
  for (const MapId id : all_maps) max_map = std::max(max_map, id.value);
  for (const MapId id : saved) {
    for (const std::shared_ptr<MapPoint>& point : atlas.map(id)->mapPoints())
      max_point = std::max(max_point, point->id().value), any_point = true;
  }
  if ((any_keyframe && state.next_ids.keyframe <= max_keyframe) || (any_point && state.next_ids.point <= max_point) ||
      state.next_ids.map <= max_map) {
    in.failAt(ids_offset, "id counters not above the file's ids (keyframe, point, map)",
              std::to_string(state.next_ids.keyframe) + ", " + std::to_string(state.next_ids.point) + ", " +
                  std::to_string(state.next_ids.map));
  }
  return state;
}

RunKeyFrames applyAtlasRunState(AtlasRunState state, Atlas& atlas) {
  AtlasFileAccess::ids(atlas).restore(state.next_ids);
  for (const auto& [id, version] : state.map_versions) AtlasFileAccess::setVersion(*atlas.map(id), version);
  for (AtlasRunState::MergedMap& merged : state.merged) {
    Map& map = AtlasFileAccess::addMergedMap(atlas, merged.id, merged.target);
    AtlasFileAccess::setOrigins(map, {}, merged.created_keyframe);
    if (merged.origin) map.setOrigin(*merged.origin);
    AtlasFileAccess::setVersion(map, merged.version);
  }
  RunKeyFrames keyframes;
  for (auto& [id, kf] : atlasKeyFrames(atlas)) keyframes.add(kf);
  KeyFrameDatabase& database = atlas.keyFrameDatabase();
  database.clear();
  for (const KeyFrameId id : state.database) {
    const std::shared_ptr<KeyFrame> kf = keyframes.find(id);
    if (kf->hasBow()) database.add(kf);
  }
  for (const KeyFrameId id : state.anchors) keyframes.find(id)->markAnchor();
  for (const KeyFrameId id : state.at_rest) AtlasFileAccess::setAtRest(*keyframes.find(id), true);
  for (AtlasRunState::CulledKeyFrame& culled : state.culled) {
    keyframes.add(AtlasFileAccess::culledKeyFrame(culled.id, culled.map, *culled.state));
  }
  for (const AtlasRunState::CulledKeyFrame& culled : state.culled) {
    AtlasFileAccess::setCulledParent(*keyframes.find(culled.id), keyframes.find(culled.culled_parent),
                                     culled.T_parent_this);
  }
  return keyframes;
}

}  // namespace ltlo::map
