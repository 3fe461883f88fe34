#pragma once
/// Loop verification and correction on a Map (namespace ltlo::loop): 3-D-3-D correspondences by BoW
/// matching, SE3 RANSAC, then the correction of ORB-SLAM's loop closing without scale (RGB-D):
/// move the current keyframe's covisible window, fuse the duplicated points, add the loop edge,
/// optimise the essential graph (SE3, or 4-DoF once gravity is known) and move every map point with
/// its keyframe.
#include <cstddef>
#include <optional>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/features/matching.h"
#include "ltlo/map/map.h"
#include "ltlo/place/se3_ransac.h"

namespace ltlo::loop {

/// Keypoint `keypoint` of the current keyframe is the same place as map point `loop_point`.
struct LoopMatch {
  int keypoint = -1;
  map::MapPointId loop_point;
};

/// correspondences[k]: p_a = current keypoint in the current camera frame (m), p_b = the loop map
/// point in the world (m); the alignment is T_c_w of the current keyframe. matches[k] is the same pair.
struct LoopCorrespondences {
  std::vector<place::Correspondence3d> correspondences;
  std::vector<LoopMatch> matches;
};

/// Matches the current keyframe's keypoints with depth (BoW, static keypoints only through the
/// keyframes' BoW) to the map points of `candidate` and its `num_covisibles` best covisibles; each
/// current keypoint and each map point is used once.
LoopCorrespondences findLoopCorrespondences(const map::KeyFrame& current, const map::KeyFrame& candidate,
                                            const map::Map& map, std::size_t num_covisibles = 5,
                                            const features::GuidedMatchOptions& matching = {});

/// An accepted loop: the corrected pose of the current keyframe and its matches to the loop side.
struct LoopClosure {
  map::KeyFrameId current;
  map::KeyFrameId loop;
  SE3 T_w_b_current_corrected;
  std::vector<LoopMatch> matches;  ///< inliers only
};

/// Geometric verification: correspondences, RANSAC (Loop.MinInliers; inlier gate chi2(3) on the
/// depth noise of the current keypoint, the distance capped at Loop.InlierThreshold), nullopt when
/// rejected. Reads the map only (thread-safe).
std::optional<LoopClosure> verifyLoop(const map::KeyFrame& current, const map::KeyFrame& candidate, const map::Map& map,
                                      const LoopOptions& options, place::Se3RansacResult* ransac_out = nullptr);

struct LoopCorrectionResult {
  int window_size = 0;         ///< keyframes moved with the current one
  int fused_points = 0;        ///< current points replaced by loop points
  int added_observations = 0;  ///< loop points newly observed by the current keyframe
  int graph_edges = 0;         ///< essential-graph edges optimised
  double initial_cost = 0.0;   ///< of the pose graph
  double final_cost = 0.0;
};

struct LoopCorrectionOptions {
  int iterations = 20;  ///< of the essential-graph optimisation
  /// Gravity in the map's world frame (m/s^2) once the IMU is initialised: the correction is then
  /// 4-DoF (yaw about gravity and translation; roll and pitch are observable through gravity), the
  /// essential graph also links keyframes consecutive in time, and keyframe velocities turn with
  /// their poses. nullopt: 6-DoF (SE3) correction, velocities untouched.
  std::optional<Vec3> g_w;
};

/// Applies `loop` to `map` (keyframes' T_w_b (and v_w_b) and points' p_w). The loop keyframe is the
/// gauge. The current keyframe's window first moves rigidly by the loop's correction (with g_w its
/// yaw and translation only, keeping the current keyframe's corrected position). Edges that existed
/// before the correction keep their pre-loop relative pose; new ones (the loop edge, connections
/// made by fusion) take the corrected poses. Points move with the keyframe that corrected them in
/// the window, else with their reference keyframe (else first observer).
/// Call with local mapping paused (it moves poses and points and changes the graph).
LoopCorrectionResult correctLoop(map::Map& map, const LoopClosure& loop,
                                 const LoopCorrectionOptions& options = LoopCorrectionOptions());

}  // namespace ltlo::loop
