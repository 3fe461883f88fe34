#include "ltlo/loop/map_merger.h"

#include "ltlo/core/log.h"

namespace ltlo::loop {

std::optional<MergeResult> mergeAtPlace(map::Atlas& atlas, const map::KeyFrame& current, const map::KeyFrame& candidate,
                                        const LoopOptions& options) {
  const map::MapId source = current.mapId();
  const map::MapId target = candidate.mapId();
  if (source == target) return std::nullopt;
  map::Map* target_map = atlas.map(target);
  if (target_map == nullptr || atlas.map(source) == nullptr) return std::nullopt;

  const std::optional<LoopClosure> place = verifyLoop(current, candidate, *target_map, options);
  if (!place) return std::nullopt;
  MergeResult result;
  result.source = source;
  result.target = target;
  result.inliers = static_cast<int>(place->matches.size());
  result.T_target_source = place->T_w_b_current_corrected * current.T_w_b().inverse();
  atlas.mergeMaps(source, target, result.T_target_source);
  log::info("merged ", source, " into ", target, " at kf ", current.id(), " ~ kf ", candidate.id(), " (",
            result.inliers, " inliers)");
  // The current keyframe is now in the target frame at (nearly) its corrected pose; the loop
  // correction fuses the duplicated points and ties the two spanning trees with the loop edge.
  result.correction = correctLoop(*target_map, *place);
  return result;
}

}  // namespace ltlo::loop
