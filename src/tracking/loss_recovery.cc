#include "ltlo/tracking/loss_recovery.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/map/binary_io.h"
#include "ltlo/tracking/tracker.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::clearMatches;
using detail::isMatched;
using detail::staticKeypointsWithDepth;

LossDecision LossRecovery::recover(map::Frame& frame, int inliers, const LossContext& context, RecoverySteps& steps,
                                   const SE3& T_w_b_pred, const Vec3& v_w_b_pred) {
  TrackingStats& stats = context.stats;
  if (inliers < context.min_inliers && context.was_lost && options_.tracking.reacquire &&
      (context.imu_link || std::isfinite(context.start_reacquire_sigma_m))) {
    // The IMU knows roughly where the camera is: look for the map there before anything else.
    // Before it is initialised, the gyroscope knows the rotation and the robot's speed bounds the
    // position (an occluded start: tracking lost behind a box that moved with the camera).
    const int reacquired = context.imu_link
                               ? steps.reacquire(frame, context.T_w_b_imu, carried_position_sigma_m_)
                               : steps.reacquire(frame, T_w_b_pred, context.start_reacquire_sigma_m);
    if (reacquired > 0) {
      inliers = reacquired;
      stats.relocalised = true;
      stats.reacquired = true;
    }
  }
  if (inliers < context.min_inliers && !stats.reacquired && context.has_vocabulary) {
    const int relocalised = steps.relocalise(frame);
    if (relocalised > 0) {
      inliers = relocalised;
      stats.relocalised = true;
    }
  }
  stats.inliers = inliers;
  frame.reference_keyframe = context.reference_kf;
  if (inliers >= context.min_inliers && context.gyro_R_w_b) {
    // Before the IMU is initialised no inertial term holds the pose optimisation's rotation, and a
    // view held by a mover can turn it in one frame by more than a robot turns in a second (320x240
    // at 15 Hz with the box over the view: 14 deg in one frame on 43 inliers, the gyroscope 0.6 deg).
    const Mat3 R_difference = context.gyro_R_w_b->transpose() * frame.T_w_b().rotationMatrix();
    const double angle_rad = so3Log(R_difference).norm();
    if (angle_rad > context.gyro_gate_rad) {
      log::info("t = ", frame.t_s(), " s: the ", stats.relocalised ? "recovered" : "tracked", " pose turned ",
                angle_rad * 180.0 / M_PI, " deg from the gyroscope's rotation (Tracking.GyroRotationGate ",
                context.gyro_gate_rad * 180.0 / M_PI, " deg): the frame is lost");
      stats.relocalised = false;
      stats.reacquired = false;
      stats.gyro_rejected = true;
      inliers = 0;
      stats.inliers = 0;
    }
  }
  if (stats.gyro_rejected) {
    // Held at the gyroscope's rotation, the camera centre of the prediction kept.
    const Vec3 t_w_c = (T_w_b_pred * frame.T_b_c()).translation();
    const SE3 T_w_b_gyro(*context.gyro_R_w_b, t_w_c - *context.gyro_R_w_b * frame.T_b_c().translation());
    return handleLostFrame(frame, context, steps, T_w_b_gyro, v_w_b_pred);
  }
  if (inliers < context.min_inliers) return handleLostFrame(frame, context, steps, T_w_b_pred, v_w_b_pred);
  LossDecision decision;
  decision.inliers = inliers;
  if (stats.reacquired) {
    decision.recovery = Recovery::kReacquired;
  } else if (stats.relocalised) {
    decision.recovery = Recovery::kRelocalised;
  }
  return decision;
}

void LossRecovery::onTrackedFrame(const map::Frame& frame, int min_inliers) {
  int anchored_inliers = 0;
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    if (isMatched(frame, i) && frame.map_points[static_cast<std::size_t>(i)] < carried_first_point_) ++anchored_inliers;
  }
  // An open IMU-carried stretch closes when the frame matches the map from before it.
  if (carried_first_point_.valid() && anchored_inliers >= min_inliers) {
    log::info("IMU-carried stretch anchored at t = ", frame.t_s(), " s: ", anchored_inliers,
              " inliers on points older than ", carried_first_point_, " after ", frame.t_s() - anchored_t_s_, " s");
    carried_first_point_ = map::MapPointId();
  }
  if (std::isnan(tracked_run_start_s_)) tracked_run_start_s_ = frame.t_s();
  if (untrusted_velocity_sigma_m_s_ > 0.0 &&
      frame.t_s() - tracked_run_start_s_ >= options_.tracking.new_map_velocity_trust_s) {
    log::debug("t = ", frame.t_s(), " s: the map started at ", untrusted_velocity_t_s_,
               " s has tracked its own velocity for ", frame.t_s() - tracked_run_start_s_, " s");
    untrusted_velocity_sigma_m_s_ = 0.0;
  }
  if (!carried_first_point_.valid()) {
    anchored_t_s_ = frame.t_s();
    carried_fix_t_s_ = frame.t_s();
    carried_fix_sigma_m_ = 0.0;
  } else if (frame.t_s() - tracked_run_start_s_ >= kCarriedFixSeconds) {
    carried_fix_t_s_ = frame.t_s();
    carried_fix_sigma_m_ = carried_placement_sigma_m_;
  }
}

double LossRecovery::velocitySigmaFloor_m_s(double t_s, double sigma_a_m_s2) const {
  if (untrusted_velocity_sigma_m_s_ <= 0.0) return 0.0;
  return std::hypot(untrusted_velocity_sigma_m_s_, sigma_a_m_s2 * std::max(0.0, t_s - untrusted_velocity_t_s_));
}

void LossRecovery::updateCarriedSigma(double t_s, double sigma_p, double sigma_a, double bias_drift_m,
                                      double lever_m) {
  // Over an IMU-carried stretch the acceleration error integrates from the last visual fix
  // (the anchored frame, or points placed at the prediction that tracking then held), on
  // top of that fix's own error (loss_recovery.h, carried_fix_t_s_).
  if (carried_first_point_.valid()) {
    const double drift_s = t_s - carried_fix_t_s_;
    carried_position_sigma_m_ =
        std::hypot(carried_fix_sigma_m_, std::hypot(sigma_p, 0.5 * sigma_a * drift_s * drift_s)) + lever_m;
  } else {
    carried_position_sigma_m_ = std::hypot(sigma_p, bias_drift_m) + lever_m;
  }
}

LossDecision LossRecovery::handleLostFrame(map::Frame& frame, const LossContext& context, RecoverySteps& steps,
                                           const SE3& T_w_b_pred, const Vec3& v_w_b_pred) {
  const TrackingStats& stats = context.stats;
  if (context.state != TrackingState::kLost) {
    log::warn("tracking lost at t = ", frame.t_s(), " s: ", stats.inliers, " inliers (", context.min_inliers,
              " needed), ", frame.numKeypoints(), " keypoints");
  }
  context.state = TrackingState::kLost;
  tracked_run_start_s_ = std::numeric_limits<double>::quiet_NaN();
  clearMatches(frame);
  steps.holdPrediction(frame, T_w_b_pred, v_w_b_pred);
  const double lost_for_s = frame.t_s() - context.last_tracked_t_s;
  log::debug("frame t = ", frame.t_s(), ": lost, ", stats.inliers, " inliers, link ", stats.inertial_link,
             ", sigma ", stats.predicted_position_sigma_m, " m, p = ", frame.T_w_b().translation().transpose(),
             ", ref ", context.reference_kf);
  const TrackingOptions& o = options_.tracking;
  const int static_with_depth = lost_for_s >= o.new_map_after_s ? staticKeypointsWithDepth(frame) : 0;
  const double sigma_m = context.imu_link ? carried_position_sigma_m_ : std::numeric_limits<double>::infinity();
  const bool keyframe_in_map = context.last_kf_ptr && !context.last_kf_ptr->isBad() &&
                               context.last_kf_ptr->mapId() == context.atlas.activeMap().id();
  const bool can_extend =
      sigma_m <= o.max_imu_position_sigma_m && keyframe_in_map && static_with_depth >= o.min_extend_features;
  LossDecision decision;
  decision.inliers = stats.inliers;
  decision.recovery = Recovery::kLost;
  if (o.new_map_after_s >= 0.0 && lost_for_s >= o.new_map_after_s &&
      (can_extend || static_with_depth >= options_.min_init_features)) {
    if (can_extend) {
      extendMap(frame, context, steps, lost_for_s, sigma_m);
      decision.recovery = Recovery::kMapExtended;
      return decision;
    }
    startNewMap(frame, context, steps, lost_for_s, sigma_m, keyframe_in_map);
    decision.recovery = Recovery::kNewMap;
    return decision;
  }
  steps.recordFramePose(frame);
  return decision;
}

void LossRecovery::extendMap(map::Frame& frame, const LossContext& context, RecoverySteps& steps, double lost_for_s,
                             double sigma_m) {
  // The IMU still knows where the camera is: what the frame sees is unmapped (revealed behind
  // an occluder, or new), so it extends the map at the predicted pose, linked by the IMU.
  log::warn("lost for ", lost_for_s, " s: keyframe at the IMU-predicted pose (position sigma ", sigma_m,
            " m) extends map ", context.atlas.activeMap().id(), " at t = ", frame.t_s(), " s");
  steps.extendMapAtPrediction(frame);
  // The new points carry the prediction's error: the fix once frames hold them (onTrackedFrame).
  carried_placement_sigma_m_ = sigma_m;
  if (!carried_first_point_.valid()) {
    // The stretch opens: every point from here on was placed by the IMU.
    for (const map::MapPointId id : frame.map_points) {
      if (id.valid() && (!carried_first_point_.valid() || id < carried_first_point_)) carried_first_point_ = id;
    }
  }
  context.stats.map_extended = true;
  context.frame_tracked = true;
  context.state = TrackingState::kOk;
  steps.recordFramePose(frame);
}

void LossRecovery::startNewMap(map::Frame& frame, const LossContext& context, RecoverySteps& steps,
                               double lost_for_s, double sigma_m, bool keyframe_in_map) {
  // New map at the predicted pose: same world frame (gravity stays valid), old map kept.
  const map::MapId parent = context.atlas.activeMap().id();
  std::optional<map::MapOrigin> origin;
  if (context.imu_predicted && context.imu_link && std::isfinite(sigma_m)) {
    // The dead reckoning placed it in the parent's world: the loop closer may rejoin the two by
    // a search within this uncertainty (Loop.Rejoin).
    origin.emplace();
    origin->parent = parent;
    origin->sigma_position_m = sigma_m;
    origin->sigma_rotation_rad = context.stats.predicted_rotation_sigma_rad;
    origin->t_s = frame.t_s();
    origin->v_w_b_dead_reckoned = frame.v_w_b();
    origin->sigma_velocity_m_s = context.stats.predicted_velocity_sigma_m_s;
    if (keyframe_in_map && context.imu_since_keyframe && !context.imu_chain_broken) {
      // The IMU from the parent's last keyframe to this frame (the new map's first keyframe).
      origin->parent_keyframe = context.last_kf;
      origin->T_w_b_parent_keyframe = context.last_kf_ptr->T_w_b();
      origin->imu_across = std::make_shared<const imu::Preintegrated>(*context.imu_since_keyframe);
    }
  }
  map::Map& created = context.atlas.createNewMap();
  ++maps_created_;
  log::warn("lost for ", lost_for_s, " s: new map ", created.id(), " at t = ", frame.t_s(), " s");
  steps.initialiseNewMap(frame);
  LTLO_ASSERT(context.state == TrackingState::kOk, "new map not initialised");
  if (origin) {
    // Before the keyframe leaves tracking (the loop closer reads the origin with it).
    if (origin->imu_across) origin->first_keyframe = context.last_kf;
    created.setOrigin(*origin);
    log::debug("new map ", created.id(), ": dead-reckoned origin, position sigma ", origin->sigma_position_m,
               " m, velocity ", origin->v_w_b_dead_reckoned.transpose(), " m/s, sigma ", origin->sigma_velocity_m_s,
               " m/s");
  }
  // Until it has tracked Tracking.NewMapVelocityTrust in a row, the map hands on no velocity more
  // certain than the one it started with (velocitySigmaFloor_m_s): a map of a few frames, perhaps
  // on an occluder's points, gives a confident marginal of a wrong velocity (issue 32, ltlo seed 5).
  untrusted_velocity_sigma_m_s_ = origin && options_.tracking.new_map_velocity_trust_s > 0.0
                                      ? origin->sigma_velocity_m_s
                                      : 0.0;
  untrusted_velocity_t_s_ = frame.t_s();
  carried_first_point_ = map::MapPointId();
  carried_fix_sigma_m_ = 0.0;
  carried_fix_t_s_ = frame.t_s();
  anchored_t_s_ = frame.t_s();
  context.stats.new_map = true;
  context.frame_tracked = true;
}

void LossRecovery::writeState(map::ByteWriter& out) const {
  out.f64(anchored_t_s_);
  out.u64(carried_first_point_.value);
  out.f64(carried_position_sigma_m_);
  out.f64(carried_placement_sigma_m_);
  out.f64(carried_fix_sigma_m_);
  out.f64(carried_fix_t_s_);
  out.f64(tracked_run_start_s_);
  out.f64(untrusted_velocity_sigma_m_s_);
  out.f64(untrusted_velocity_t_s_);
}

void LossRecovery::readState(map::ByteReader& in) {
  anchored_t_s_ = in.finiteF64("anchored time");
  carried_first_point_ = map::MapPointId(in.u64("carried stretch's first point"));
  // Infinite before the first IMU prediction, like the live value.
  const std::uint64_t sigma_offset = in.fileOffset();
  carried_position_sigma_m_ = in.f64("carried position sigma");
  if (std::isnan(carried_position_sigma_m_) || carried_position_sigma_m_ < 0.0) {
    in.failAt(sigma_offset, "carried position sigma is not a sigma", map::exactNumberText(carried_position_sigma_m_));
  }
  carried_placement_sigma_m_ = in.finiteF64("carried placement sigma");
  carried_fix_sigma_m_ = in.finiteF64("carried fix sigma");
  carried_fix_t_s_ = in.finiteF64("carried fix time");
  // NaN after a lost frame, like the live value.
  const std::uint64_t start_offset = in.fileOffset();
  tracked_run_start_s_ = in.f64("tracked run start");
  if (std::isinf(tracked_run_start_s_)) {
    in.failAt(start_offset, "tracked run start is infinite", map::exactNumberText(tracked_run_start_s_));
  }
  const std::uint64_t untrusted_offset = in.fileOffset();
  untrusted_velocity_sigma_m_s_ = in.finiteF64("untrusted velocity sigma");
  if (untrusted_velocity_sigma_m_s_ < 0.0) {
    in.failAt(untrusted_offset, "untrusted velocity sigma is not a sigma",
              map::exactNumberText(untrusted_velocity_sigma_m_s_));
  }
  untrusted_velocity_t_s_ = in.finiteF64("untrusted velocity time");
}

}  // namespace ltlo::tracking
