#pragma once
/// Map merging (namespace ltlo::loop): when a keyframe of the active map recognises a place of
/// another Atlas map, align the two by the same 3-D-3-D RANSAC as a loop, move the active map into
/// the other's frame (Atlas::mergeMaps) and close the loop across the seam (fusion, loop edge,
/// essential graph).
#include <optional>

#include "ltlo/core/settings.h"
#include "ltlo/loop/loop_corrector.h"
#include "ltlo/map/atlas.h"

namespace ltlo::loop {

struct MergeResult {
  map::MapId source;    ///< the map of `current`, merged away
  map::MapId target;    ///< the map of the recognised place, kept
  SE3 T_target_source;  ///< applied to everything of `source`
  int inliers = 0;      ///< RANSAC inliers of the place match
  LoopCorrectionResult correction;
};

/// nullopt (and nothing changed) when both keyframes are in the same map or the place match fails
/// verification. Call with tracking and local mapping paused on both maps.
std::optional<MergeResult> mergeAtPlace(map::Atlas& atlas, const map::KeyFrame& current, const map::KeyFrame& candidate,
                                        const LoopOptions& options);

}  // namespace ltlo::loop
