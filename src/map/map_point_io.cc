// The points section of the atlas file (atlas_file.h): every map point with its observations.
#include <algorithm>
#include <string>

#include "atlas_file_access.h"
#include "atlas_file_sections.h"

namespace ltlo::map {

namespace {

constexpr std::size_t kObservationBytes = 8 + 4;

void writeMapPoint(const MapPoint& point, MapId map, const AtlasSnapshot& snapshot, ByteWriter& out) {
  out.u64(map.value);
  out.u64(point.id().value);
  out.vec3(point.p_w());
  out.u64(savedOrInvalid(snapshot, point.referenceKeyFrame()));
  for (const std::uint64_t word : point.descriptor()) out.u64(word);
  out.vec3(point.normal_w());
  out.f64(point.minDistance_m());
  out.f64(point.maxDistance_m());
  out.i32(point.numVisible());
  out.i32(point.numFound());
  out.f64(point.beta());
  Observations observations = point.observations();
  observations.erase(std::remove_if(observations.begin(), observations.end(),
                                    [&](const std::pair<KeyFrameId, int>& entry) { return !snapshot.saved(entry.first); }),
                     observations.end());
  out.u64(observations.size());
  for (const auto& [kf, index] : observations) {
    out.u64(kf.value);
    out.i32(index);
  }
}

/// Reads one point, links its observations and inserts it into its map.
void readMapPoint(ByteReader& in, AtlasRestore& restore) {
  Map& map = readKnownMap(in, restore, "map point map");
  const std::uint64_t id_offset = in.fileOffset();
  const MapPointId id(in.u64("map point id"));
  if (!id.valid() || restore.points.count(id) > 0)
    in.failAt(id_offset, "map point id invalid or repeated", std::to_string(id.value));
  const Vec3 p_w = in.vec3("map point position");
  const KeyFrameId reference = readKnownKeyFrame(in, restore, "reference keyframe", true);
  auto point = std::make_shared<MapPoint>(id, p_w, reference);
  features::Descriptor descriptor;
  for (std::uint64_t& word : descriptor) word = in.u64("map point descriptor");
  point->setDescriptor(descriptor);
  const Vec3 normal_w = in.vec3("map point normal");
  // Non-negative: predictScale takes the log of max_distance_m over a distance.
  const double min_distance_m = in.f64InRange("map point min distance", 0.0, 1e12);
  const double max_distance_m = in.f64InRange("map point max distance", 0.0, 1e12);
  point->setNormalAndDistances(normal_w, min_distance_m, max_distance_m);
  // Far below INT_MAX: tracking keeps adding to them (and a fusion adds one point's to another's).
  constexpr std::int32_t kMaxCount = 1 << 30;
  const int num_visible = in.i32InRange("visible count", 0, kMaxCount);
  const int num_found = in.i32InRange("found count", 0, kMaxCount);
  AtlasFileAccess::setCounts(*point, num_visible, num_found);
  point->setBeta(in.f64InRange("beta", 0.0, 1.0));
  const std::size_t num_observations = in.count("observations", kObservationBytes);
  for (std::size_t k = 0; k < num_observations; ++k) {
    const std::uint64_t offset = in.fileOffset();
    const KeyFrameId kf_id = readKnownKeyFrame(in, restore, "observing keyframe", false);
    KeyFrame& kf = *restore.keyframes.at(kf_id);
    const std::int32_t index = in.i32InRange("observed keypoint", 0, kf.numKeypoints() - 1);
    // Both ends at once; refused when the keypoint already holds a point or the point is seen
    // twice in one keyframe (a link the live map never makes).
    if (!map.addObservation(kf, index, *point)) {
      in.failAt(offset, "observation conflicts with another link of " + std::to_string(kf_id.value),
                "keypoint " + std::to_string(index));
    }
  }
  AtlasFileAccess::insert(map, point);
  restore.points.emplace(id, std::move(point));
}

}  // namespace

void writePointsSection(const AtlasSnapshot& snapshot, ByteWriter& out) {
  out.u64(snapshot.point_ids.size());
  for (const AtlasSnapshot::MapEntry& entry : snapshot.maps) {
    for (const std::shared_ptr<MapPoint>& point : entry.points) writeMapPoint(*point, entry.map->id(), snapshot, out);
  }
}

void readPointsSection(ByteReader& in, AtlasRestore& restore) {
  constexpr std::size_t kMinPointBytes = 8 + 8 + 24 + 8 + 32 + 24 + 16 + 8 + 8 + 8;
  const std::size_t n = in.count("map points", kMinPointBytes);
  for (std::size_t k = 0; k < n; ++k) readMapPoint(in, restore);
  in.expectEnd();
}

}  // namespace ltlo::map
