#pragma once
/// Place matching of a window of keyframes of one map against another map, pooled (namespace
/// ltlo::place): the guided window search of guided_place_match.h run for every keyframe of the
/// window at the prediction the first keyframe's prediction gives it through their relative pose in
/// their own map, the matches pooled into the first keyframe's camera frame, one 3-D-3-D RANSAC over
/// all of them and a refinement with each match's own anisotropic RGB-D noise.
///
/// Why: a rejoin after a long occlusion is searched from a map tracked through the few percent of
/// the view the occluder leaves; one keyframe then holds 15-20 right matches in a narrow fan, too
/// few to accept and too narrow to fix the yaw, while its neighbours see the same static strip from
/// a few decimetres further on. A young map's relative poses are millimetre-accurate where its
/// absolute pose (dead-reckoned) is decimetres off, so the window acts as one wider view.
/// Reads both maps only (thread-safe).
#include <memory>
#include <vector>

#include "ltlo/place/guided_place_match.h"

namespace ltlo::place {

/// The first keyframe of the window, its best covisibles in its own map after it (at most
/// max_keyframes in all, none bad).
std::vector<std::shared_ptr<map::KeyFrame>> poolingWindow(const std::shared_ptr<map::KeyFrame>& kf,
                                                          const map::Map& map, int max_keyframes);

/// The pooled search. window.front() is the keyframe placed and T_w_c_pred its predicted camera
/// pose in `target`'s world; the other keyframes are placed by their poses relative to it. Each
/// map point of `target` takes part once (its best descriptor match over the window). The result
/// is in GuidedPlaceMatch's terms for window.front(): T_w_c its pose in target's world, matches its
/// own inliers (keypoint -> map point of target), views the keyframes pooled, correspondences,
/// ransac_inliers and refined_inliers over the whole window, yaw_sigma_rad from the marginal
/// information of the refinement's inliers (with hold_rotation: infinity). success needs
/// options.min_ransac_inliers refined inliers (over the window) and, with options.apply_gate, the
/// pose within the gate around T_w_c_pred. With hold_rotation the rotation stays T_w_c_pred's and
/// only the translation is solved (a prediction whose rotation is better known than the matches
/// fix it).
GuidedPlaceMatch pooledPlaceMatch(const std::vector<std::shared_ptr<map::KeyFrame>>& window,
                                  const map::Map& target, const SE3& T_w_c_pred,
                                  const GuidedPlaceMatchOptions& options, bool hold_rotation = false);

}  // namespace ltlo::place
