// Tracker, part 4: guided re-acquisition of the active map by a lost frame after an IMU-only
// stretch (Tracking.Reacquire). When vision comes back after seconds of IMU dead-reckoning, the
// predicted pose is off by more than the usual search windows allow (0.5 sigma_a t^2: 0.24 m after
// 4 s at 0.03 m/s^2), and the map around it may no longer be the local map of the last tracked
// frame. The map points of the keyframes around the predicted pose are projected with it and
// matched to the frame's static keypoints with depth in windows of the predicted reprojection's
// uncertainty; a 3-D-3-D RANSAC pose (depth on both sides) must agree with the prediction within
// Tracking.ReacquireGateSigmas of its standard deviation, and is then refined like a
// relocalisation (pose optimisation, local-map search, the IMU link to the previous frame).
#include <cmath>

#include "ltlo/core/log.h"
#include "ltlo/place/guided_place_match.h"
#include "ltlo/tracking/tracker.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::clearMatches;
using detail::staticKeypointsWithDepth;

place::GuidedPlaceMatchOptions reacquireSearchOptions(const TrackerOptions& options) {
  place::GuidedPlaceMatchOptions search;
  search.gate_sigmas = options.tracking.reacquire_gate_sigmas;
  search.min_rotation_gate_deg = options.tracking.reacquire_min_rotation_gate_deg;
  search.min_radius_px = options.local_map_radius_px;
  search.max_radius_px = options.tracking.reacquire_max_radius_px;
  search.max_keyframes = options.max_local_keyframes;
  search.max_descriptor_distance = options.max_descriptor_distance;
  search.min_ransac_inliers = options.relocalisation.min_ransac_inliers;
  return search;
}

int Tracker::reacquire(map::Frame& frame, const SE3& T_w_b_pred) {
  const TrackingOptions& o = options_.tracking;
  const double sigma_p = carried_position_sigma_m_;
  const double sigma_r = stats_.predicted_rotation_sigma_rad;
  if (!std::isfinite(sigma_p) || staticKeypointsWithDepth(frame) < o.reacquire_min_inliers) return 0;
  map::Map& active = activeMap();
  const SE3 T_w_c_pred = T_w_b_pred * frame.T_b_c();
  const Vec3 centre_w = T_w_c_pred.translation();

  place::GuidedPlaceMatchOptions search = reacquireSearchOptions(options_);
  search.sigma_position_m = sigma_p;
  search.sigma_rotation_rad = sigma_r;
  search.seed = static_cast<std::uint32_t>(std::llround(frame.t_s() * 1000.0)) * 7919u + 29u;
  const place::GuidedPlaceMatch found = place::guidedPlaceMatch(frame, active, T_w_c_pred, search);
  log::debug("re-acquisition at t = ", frame.t_s(), " s: sigma ", sigma_p, " m / ", sigma_r, " rad, ",
             found.keyframes, " keyframes, ", found.projected, " points projected, ", found.correspondences,
             " matches of ", staticKeypointsWithDepth(frame), " static keypoints with depth, ", found.ransac_inliers,
             " RANSAC inliers, ", found.distance_m, " m / ", found.rotation_rad * 180.0 / M_PI,
             " deg from the prediction", found.success ? "" : ": rejected");
  if (!found.success) return 0;

  // Refinement as a relocalisation: vision alone (the prediction's uncertainty no longer widens
  // the windows), then the local map of the matched points.
  const map::KeyFrameId reference_before = reference_kf_;
  const std::shared_ptr<map::KeyFrame> reference_ptr_before = reference_kf_ptr_;
  const double saved_sigma_p = stats_.predicted_position_sigma_m;
  const double saved_sigma_r = stats_.predicted_rotation_sigma_rad;
  stats_.predicted_position_sigma_m = 0.0;
  stats_.predicted_rotation_sigma_rad = 0.0;
  clearMatches(frame);
  for (const auto& [keypoint, point] : found.matches) frame.map_points[static_cast<std::size_t>(keypoint)] = point;
  frame.setPose_T_w_c(found.T_w_c);
  int inliers = optimisePose(frame, frame.T_w_b(), true);
  if (inliers >= search.min_ransac_inliers) {
    updateLocalMap(frame);
    searchLocalMap(frame);
    inliers = optimisePose(frame, frame.T_w_b(), false);
  }
  stats_.predicted_position_sigma_m = saved_sigma_p;
  stats_.predicted_rotation_sigma_rad = saved_sigma_r;
  const bool refined_within_gate = place::withinPredictionGate(frame.T_w_c(), T_w_c_pred, search);
  if (inliers >= o.reacquire_min_inliers && refined_within_gate) {
    log::info("re-acquired map ", active.id(), " at t = ", frame.t_s(), " s after ", frame.t_s() - last_tracked_t_s_,
              " s lost: ", found.ransac_inliers, " RANSAC inliers of ", found.correspondences, ", ", inliers,
              " after the local map, ", (frame.T_w_c().translation() - centre_w).norm(),
              " m from the IMU prediction (sigma ", sigma_p, " m)");
    return std::max(inliers, optimiseStateAfterGap(frame));
  }
  log::debug("re-acquisition: ", inliers, " inliers after the local map (", o.reacquire_min_inliers, " needed)",
             refined_within_gate ? "" : ", refined pose outside the gate");
  reference_kf_ = reference_before;
  reference_kf_ptr_ = reference_ptr_before;
  clearMatches(frame);
  return 0;
}

}  // namespace ltlo::tracking
