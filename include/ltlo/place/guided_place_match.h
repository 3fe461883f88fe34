#pragma once
/// Place matching guided by a pose prediction (namespace ltlo::place): the map points of the
/// keyframes of a map around a predicted camera pose are projected with it and matched to the
/// static keypoints with depth of a view (a Frame or a KeyFrame) in windows of the prediction's
/// uncertainty; a 3-D-3-D RANSAC pose (depth on both sides) must then agree with the prediction
/// within gate_sigmas of its standard deviation.
///
/// Used where the IMU knows roughly where the camera is but the pose is beyond the usual search
/// windows: the tracker's re-acquisition of its map after an IMU-only stretch
/// (Tracking.Reacquire), and the loop closer's rejoin of a map started after such a stretch with
/// the map it came from (Loop.Rejoin), whose world frame it shares up to the dead-reckoning error.
/// Reads the map only (thread-safe).
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/map/map.h"
#include "ltlo/place/se3_ransac.h"

namespace ltlo::place {

struct GuidedPlaceMatchOptions {
  double sigma_position_m = 0.1;     ///< standard deviation of the predicted camera position
  double sigma_rotation_rad = 0.01;  ///< standard deviation of the predicted rotation
  double gate_sigmas = 3.0;          ///< windows and the pose gate, in standard deviations
  double min_rotation_gate_deg = 3.0;
  double min_radius_px = 15.0;       ///< window radius floor (at level 0)
  double max_radius_px = 160.0;      ///< window radius cap (at level 0)
  int max_keyframes = 20;            ///< nearest keyframes looking the same way
  /// Only keyframes within this distance of the predicted camera (m) and older than
  /// max_keyframe_t_s, none of `excluded_keyframes` (a loop search leaves out the current
  /// keyframe's own neighbourhood).
  double max_keyframe_distance_m = std::numeric_limits<double>::infinity();
  double max_keyframe_t_s = std::numeric_limits<double>::infinity();
  std::vector<map::KeyFrameId> excluded_keyframes;
  int max_descriptor_distance = 50;
  /// Ratio test of the wide-window matching: a window of k sigma holds most of the view's static
  /// keypoints, so the second best is the best of many random descriptors; the RANSAC and the gate
  /// remove what the looser test lets through.
  double ratio = 0.9;
  int min_ransac_inliers = 15;
  /// With the looser ratio test a fifth of the matches may be right; 1000 draws of three find an
  /// all-inlier sample with probability 1 - (1 - 0.2^3)^1000 > 0.999.
  int ransac_iterations = 1000;
  std::uint32_t seed = 29;
  /// Reject a pose outside the gate around the prediction (else the caller gates it, e.g. against
  /// another pose when the prediction is a hypothesis of its own).
  bool apply_gate = true;
  /// Refine the RANSAC pose by a vision-only pose optimisation on its inliers (reprojection and
  /// depth: the 3-D-3-D alignment of distant points trades rotation for translation), the
  /// optimisation's inliers becoming the matches; bf of its RGB-D edges (px m).
  bool refine_pose = false;
  double bf_px_m = 40.0;
};

struct GuidedPlaceMatch {
  bool success = false;  ///< enough RANSAC inliers and within the gate
  SE3 T_w_c;             ///< the RANSAC pose, or its refinement (valid with success)
  /// RANSAC inliers: keypoint of the view -> map point (with success).
  std::vector<std::pair<int, map::MapPointId>> matches;
  /// The searched keyframe nearest to the RANSAC pose (with success; for a loop edge).
  std::shared_ptr<map::KeyFrame> nearest_keyframe;
  int keyframes = 0;        ///< keyframes searched
  int projected = 0;        ///< their points inside the image at the prediction
  int correspondences = 0;  ///< matches given to the RANSAC
  int ransac_inliers = 0;
  int refined_inliers = 0;    ///< of the pose optimisation (refine_pose)
  int views = 1;              ///< keyframes pooled (pooled_place_match.h)
  double distance_m = 0.0;    ///< of the RANSAC pose from the prediction
  double rotation_rad = 0.0;  ///< likewise
  /// With refine_pose: standard deviation of the refined pose's rotation about the world z axis
  /// (gravity once the IMU is initialised), from the marginal pose information of its inliers. A
  /// view whose matches crowd into a small patch at one depth cannot tell a turn about z from a
  /// sideways step; a 4-DoF correction built on it turns the map by that ambiguity.
  double yaw_sigma_rad = std::numeric_limits<double>::infinity();
};

/// A static keypoint with depth of a view matched to a map point in the window around its
/// projection at the prediction.
struct WindowMatch {
  int keypoint = -1;
  map::MapPointId point;
  Vec3 p_w = Vec3::Zero();  ///< the map point's position
  int distance = 257;       ///< descriptor distance
};

/// The window search of guidedPlaceMatch without its RANSAC: the points of the map's keyframes
/// around T_w_c_pred projected with it, each matched to the best static keypoint with depth in the
/// window of the prediction's uncertainty (descriptor distance and ratio test), each keypoint kept
/// for its best point; keypoint order. The counts of searched keyframes and projected points are
/// written when not null.
template <class View>
std::vector<WindowMatch> windowMatches(const View& view, const map::Map& map, const SE3& T_w_c_pred,
                                       const GuidedPlaceMatchOptions& options, int* keyframes = nullptr,
                                       int* projected = nullptr);

/// Of the keyframes the search around T_w_c_pred covers, the one nearest to `t_w_c` (null if none).
std::shared_ptr<map::KeyFrame> nearestSearchedKeyFrame(const map::Map& map, const SE3& T_w_c_pred,
                                                       const GuidedPlaceMatchOptions& options, const Vec3& t_w_c);

/// `View` is map::Frame or map::KeyFrame (keypoints, descriptors, depths, static flags, camera).
template <class View>
GuidedPlaceMatch guidedPlaceMatch(const View& view, const map::Map& map, const SE3& T_w_c_pred,
                                  const GuidedPlaceMatchOptions& options);

/// `found` (a success) solved again with the rotation held at T_w_c_pred's: the translation is the
/// mean of its matches' 3-D differences (map point minus the view's point turned into the world,
/// depth on both sides, weighted by the depth noise), after a median start, keeping the matches
/// within 3 of their standard deviations (at least `min_inlier_m`). For a view whose matches cannot
/// fix its yaw (a narrow fan of matches beside an occluder) while the prediction's rotation is
/// better known (an IMU-carried pose: gyro drift, roll and pitch from gravity). success is false
/// below min_inliers matches; yaw_sigma_rad is then the prediction's own, not the matches'.
template <class View>
GuidedPlaceMatch translationWithHeldRotation(const View& view, const map::Map& map, const GuidedPlaceMatch& found,
                                             const SE3& T_w_c_pred, int min_inliers, double min_inlier_m = 0.03);

/// A translation of the view's world frame against the map's, found by voting.
struct WorldOffsetVote {
  bool found = false;
  Vec3 offset_w = Vec3::Zero();  ///< add to the view's positions to reach the map's world (m)
  int support = 0;               ///< votes around the peak
  int pairs = 0;                 ///< votes cast
};

/// Hough voting for the offset between where the prediction puts the view's points and where the
/// map has them: every static keypoint with depth, placed in the world by T_w_c_pred, votes for
/// (map point - keypoint) with each point of the searched keyframes (as guidedPlaceMatch) within
/// gate_sigmas of the position sigma whose descriptor is within `max_descriptor_distance`. Right
/// pairs share one offset, wrong ones scatter, so the peak (bins of `bin_m`, summed over their 27
/// neighbours) stands out even when a per-point window holds many look-alikes. found when the
/// peak has at least min_ransac_inliers votes. The rotation is taken as predicted (its error
/// spreads the peak by sigma_rotation_rad times the depth).
template <class View>
WorldOffsetVote voteWorldOffset(const View& view, const map::Map& map, const SE3& T_w_c_pred,
                                const GuidedPlaceMatchOptions& options, int max_descriptor_distance,
                                double bin_m = 0.05);

/// The RANSAC settings of a guided search (its inliers, iterations and seed).
Se3RansacOptions ransacOptionsOf(const GuidedPlaceMatchOptions& options);

/// The gate: `T_w_c` within gate_sigmas of the prediction (position, and rotation with the floor
/// min_rotation_gate_deg); the distances are written when not null.
bool withinPredictionGate(const SE3& T_w_c, const SE3& T_w_c_pred, const GuidedPlaceMatchOptions& options,
                          double* distance_m = nullptr, double* rotation_rad = nullptr);

}  // namespace ltlo::place
