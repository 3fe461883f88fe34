// Tracker, part 4: the searches of a lost frame the loss policy (loss_recovery.h) runs: the guided
// re-acquisition of the active map after an IMU-only stretch (Tracking.Reacquire) and the BoW
// relocalisation, each followed by the state's re-optimisation with the IMU link across the gap.
//
// Re-acquisition. When vision comes back after seconds of IMU dead-reckoning, the
// predicted pose is off by more than the usual search windows allow (0.5 sigma_a t^2: 0.24 m after
// 4 s at 0.03 m/s^2), and the map around it may no longer be the local map of the last tracked
// frame. The map points of the keyframes around the predicted pose are projected with it and
// matched to the frame's static keypoints with depth in windows of the predicted reprojection's
// uncertainty; a 3-D-3-D RANSAC pose (depth on both sides) must agree with the prediction within
// Tracking.ReacquireGateSigmas of its standard deviation, and is then refined like a
// relocalisation (pose optimisation, local-map search, the IMU link to the previous frame).
#include <algorithm>
#include <cmath>

#include "bow/vocabulary.h"
#include "ltlo/core/log.h"
#include "ltlo/optim/pose_only_problem.h"
#include "ltlo/place/guided_place_match.h"
#include "ltlo/tracking/tracker.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::clearMatches;
using detail::staticKeypointsWithDepth;

namespace {

/// The state information with the pose marginalised out (only velocity and biases kept, zero pose
/// block): the previous frame's prior after a relocalisation, whose predicted pose is not trusted.
Mat15 velocityAndBiasInformation(const Mat15& information) {
  Eigen::PermutationMatrix<15> order;  // [v; b_g; b_a; pose] <- [pose; v; b_g; b_a]
  for (int i = 0; i < 15; ++i) order.indices()[i] = (i + 9) % 15;
  const MatX permuted = order * information * order.transpose();
  Mat15 out = Mat15::Zero();
  out.bottomRightCorner<9, 9>() = optim::marginalInformation(permuted, 9);
  return out;
}

}  // namespace

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

int Tracker::reacquire(map::Frame& frame, const SE3& T_w_b_pred, double sigma_position_m) {
  const TrackingOptions& o = options_.tracking;
  const double sigma_p = sigma_position_m;
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

int Tracker::relocalise(map::Frame& frame) {
  if (vocabulary_ == nullptr) return 0;
  if (!frame.hasBow()) frame.computeBow(*vocabulary_);
  map::Map& active = activeMap();
  const std::vector<RelocalisationHypothesis> hypotheses =
      relocalisationHypotheses(frame, active, atlas_.keyFrameDatabase(), options_.relocalisation);
  const map::KeyFrameId reference_before = reference_kf_;
  const std::shared_ptr<map::KeyFrame> reference_ptr_before = reference_kf_ptr_;
  // Hypotheses are posed by vision alone: the predicted uncertainty does not widen their searches.
  const double sigma_p = stats_.predicted_position_sigma_m;
  const double sigma_r = stats_.predicted_rotation_sigma_rad;
  stats_.predicted_position_sigma_m = 0.0;
  stats_.predicted_rotation_sigma_rad = 0.0;
  for (const RelocalisationHypothesis& hypothesis : hypotheses) {
    clearMatches(frame);
    for (const auto& [i, id] : hypothesis.matches) frame.map_points[static_cast<std::size_t>(i)] = id;
    frame.setPose_T_w_c(hypothesis.T_w_c);
    int inliers = optimisePose(frame, frame.T_w_b(), true);
    if (inliers < options_.relocalisation.min_ransac_inliers) continue;
    updateLocalMap(frame);
    searchLocalMap(frame);
    inliers = optimisePose(frame, frame.T_w_b(), false);
    log::debug("relocalisation against keyframe ", hypothesis.keyframe, ": ", hypothesis.matches.size(),
               " RANSAC inliers, ", inliers, " after the local map");
    if (inliers >= options_.min_relocalisation_inliers) {
      log::info("relocalised at t = ", frame.t_s(), " s against keyframe ", hypothesis.keyframe, " with ", inliers,
                " inliers");
      stats_.predicted_position_sigma_m = sigma_p;
      stats_.predicted_rotation_sigma_rad = sigma_r;
      return std::max(inliers, optimiseStateAfterGap(frame));
    }
  }
  stats_.predicted_position_sigma_m = sigma_p;
  stats_.predicted_rotation_sigma_rad = sigma_r;
  reference_kf_ = reference_before;
  reference_kf_ptr_ = reference_ptr_before;
  clearMatches(frame);
  return 0;
}

int Tracker::optimiseStateAfterGap(map::Frame& frame) {
  if (!imu_prediction_.link || !frame.imu_from_last_frame || !prev_information_.valid) return 0;
  // The state after the gap: the relocalised pose with the IMU link to the previous (predicted)
  // frame, whose pose is not trusted: its prior keeps velocity and biases only.
  optim::InertialLink link;
  link.T_w_b_prev = prev_T_w_b_;
  link.v_w_b_prev = prev_v_w_b_;
  link.bias_prev = prev_bias_;
  link.g_w = g_w_;
  link.pim = std::make_shared<const imu::Preintegrated>(*frame.imu_from_last_frame);
  link.prev_prior = optim::PreviousStatePrior{velocityAndBiasInformation(prev_information_.information)};
  const int inertial_inliers = optimisePose(frame, frame.T_w_b(), false, &link);
  log::debug("relocalised state with the IMU link: ", inertial_inliers, " inliers, v = ", frame.v_w_b().transpose());
  return inertial_inliers;
}

}  // namespace ltlo::tracking
