#pragma once
/// Relocalisation of a lost frame against the keyframes of one map (namespace ltlo::tracking):
/// BoW place candidates from the keyframe database, BoW-guided matching of the frame's static
/// keypoints with depth to each candidate's map points, then a 3-D-3-D SE3 RANSAC (camera points
/// vs world points). The tracker refines the result (pose optimisation, local-map search).
#include <optional>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/ids.h"
#include "ltlo/map/keyframe_database.h"
#include "ltlo/map/map.h"

namespace ltlo::tracking {

struct RelocalisationOptions {
  /// candidates tried at most (best BoW group first)
  int max_candidates = 5;
  /// RANSAC inliers needed before the pose is refined
  int min_ransac_inliers = 15;
  /// BoW-guided matching: Hamming threshold and ratio test
  int max_descriptor_distance = 50;
  double ratio = 0.75;
};

/// One candidate pose: the camera pose found and the frame's keypoint -> map point matches
/// (RANSAC inliers only).
struct RelocalisationHypothesis {
  map::KeyFrameId keyframe;  ///< the candidate keyframe
  SE3 T_w_c;
  std::vector<std::pair<int, map::MapPointId>> matches;
  int correspondences = 0;   ///< 3-D-3-D correspondences before RANSAC
};

/// Hypotheses for `frame` (which must have its BoW computed) in map `map` (the database is filtered
/// by `map.id()`), best candidate first; empty when no candidate passes RANSAC.
std::vector<RelocalisationHypothesis> relocalisationHypotheses(const map::Frame& frame, const map::Map& map,
                                                               const map::KeyFrameDatabase& database,
                                                               const RelocalisationOptions& options);

}  // namespace ltlo::tracking
