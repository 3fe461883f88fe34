#include "ltlo/tracking/tracker.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::clearMatches;
using detail::isMatched;
using detail::staticKeypointsWithDepth;

namespace {
/// Tracking.StartMotionCheck's spacing of the poses of a window, s: 1 mm of tracking noise is then
/// about 0.25 m/s^2 of gravity, while the 0.3-0.5 m/s a robot's motion missed while tracking
/// followed a mover is 3-5 m/s^2.
constexpr double kStartMotionWindowS = 0.1;
}  // namespace

const char* trackingStateName(TrackingState state) {
  switch (state) {
    case TrackingState::kNotInitialised: return "not-initialised";
    case TrackingState::kOk: return "ok";
    case TrackingState::kLost: return "lost";
  }
  return "?";
}

Tracker::Tracker(map::Atlas& atlas, const TrackerOptions& options, std::vector<float> level_sigma2)
    : atlas_(atlas),
      options_(options),
      level_sigma2_(std::move(level_sigma2)),
      loss_(options),
      loaded_start_pending_(options.start_in_loaded_atlas),
      velocity_unknown_(options.start_in_loaded_atlas),
      start_motion_(imu::PoseGravityCheckOptions{kStartMotionWindowS, options.tracking.start_motion_check_m_s2}) {
  LTLO_ASSERT(!level_sigma2_.empty(), "the tracker needs the per-level keypoint variances");
  LTLO_ASSERT(!options_.tracking.localisation_only || options_.start_in_loaded_atlas,
              "localisation only needs a loaded atlas to localise in");
}

void Tracker::forceLost() {
  if (state_ != TrackingState::kNotInitialised) state_ = TrackingState::kLost;
}

TrackingState Tracker::track(map::Frame& frame) {
  const TrackingState state = trackFrame(frame);
  if (!provisional_points_.empty() && state != TrackingState::kNotInitialised) checkProvisionalPoints(frame);
  checkStartMotion(frame, state);
  if (options_.tracking.localisation_only) updateLocalisationImu(frame, frame_map_localised_);
  return state;
}

TrackingState Tracker::trackFrame(map::Frame& frame) {
  frame_map_localised_ = false;
  stats_ = TrackingStats();
  frame_tracked_ = false;
  frame_information_ = StateInformation();
  pose_sigma_m_ = std::numeric_limits<double>::infinity();
  imu_prediction_ = ImuPrediction();
  start_predicted_T_w_b_.reset();
  frame_posed_before_map_ = false;
  updateStandstill(frame);
  if (state_ != TrackingState::kNotInitialised || loaded_start_pending_) first_map_started_ = true;
  if (state_ == TrackingState::kNotInitialised) {
    segment(frame, MotionPrior());
    const bool plain_start = !loaded_start_pending_;
    if (plain_start && !first_map_started_ && options_.tracking.pre_map_imu_pose) poseBeforeFirstMap(frame);
    state_ = loaded_start_pending_ ? startInLoadedAtlas(frame) : initialise(frame);
    frame_tracked_ = state_ == TrackingState::kOk;
    // The map's first keyframe was made without any motion seen: its points are provisional.
    if (frame_tracked_ && plain_start && reference_kf_ptr_) {
      makeStartPointsProvisional(*reference_kf_ptr_);
    }
    if (state_ != TrackingState::kNotInitialised) {
      // The map started at the frame's pose (the dead-reckoned one with Tracking.PreMapImuPose).
      first_map_started_ = true;
      frame_posed_before_map_ = false;
      pre_map_.reset();
    }
    return state_;
  }
  LTLO_ASSERT(last_frame_.has_value(), "tracking without a last frame");
  {
    map::Map& active = activeMap();
    if (active.id() != map_id_ || active.version() != map_version_) refreshAfterMapChange(active);
  }
  clearMatches(frame);
  accumulateImuSinceKeyFrame(frame);

  const bool was_lost = state_ == TrackingState::kLost;
  const SE3 T_w_b_pred = segmentAtPrediction(frame, predictPose_T_w_b(frame));
  const Vec3 v_w_b_pred = frame.v_w_b();
  // At rest (zero-velocity update, tracker_standstill.cc) the search starts from the held pose.
  const bool hold = holdingStill();
  if (!hold) link_last_frame_after_rest_ = false;
  const SE3 T_w_b_start = hold ? prev_T_w_b_ : T_w_b_pred;
  frame.setPose_T_w_b(T_w_b_start);
  const int matched = trackWithMotionModel(frame, T_w_b_start);
  if (hold && stillConfirmedByView(frame)) return trackStill(frame, matched, was_lost);
  const LossDecision decision =
      loss_.recover(frame, matched, lossContext(frame, was_lost), *this, T_w_b_pred, v_w_b_pred);
  if (!decision.tracked()) return state_;
  recordTrackedFrame(frame, decision.inliers, was_lost);
  if (stats_.relocalised) onStartRecovery(frame);
  if (velocity_unknown_) estimateStartVelocity(frame, was_lost || stats_.relocalised);
  const KeyFrameDecision keyframe = decideKeyFrame();
  if (keyframe.deferred_on_revisit) ++keyframes_deferred_on_revisit_;
  if ((keyframe.need || keyframe.deferred_on_revisit) && log::level() <= log::Level::kDebug) {
    const MappedView view = keyframe.view.inliers > 0 ? keyframe.view : mappedView();
    log::debug("keyframe decision at t = ", frame.t_s(), ": ", keyframe.need ? "made" : "deferred on revisit",
               " (interval ", keyframe.interval, ", overlap ", keyframe.low_overlap, " ", stats_.overlap, ", weak ",
               keyframe.weak, "), inliers ", view.inliers, ", mapped ", view.mappedShare(), ", new ", view.unmatched,
               " of ", view.static_with_depth, " static with depth");
  }
  if (keyframe.need) {
    createKeyFrame();
    frame.map_points = last_frame_->map_points;
    frame.outliers = last_frame_->outliers;
    frame.reference_keyframe = reference_kf_;
  }
  recordFramePose(frame);
  if (options_.tracking.localisation_only) keepOdometryPoints(frame);
  log::debug("frame t = ", frame.t_s(), ": tracked, ", decision.inliers, " inliers, link ", stats_.inertial_link,
             ", sigma ", stats_.predicted_position_sigma_m, " m, p = ", frame.T_w_b().translation().transpose(),
             ", ref ", reference_kf_);
  return state_;
}

void Tracker::accumulateImuSinceKeyFrame(const map::Frame& frame) {
  // Accumulate the IMU since the last keyframe even across lost frames (system/ needs the chain),
  // O(1) per frame. While lost it is bounded: beyond max_lost_imu_interval_s it is re-anchored on
  // the predicted state (the frame-to-frame prediction goes on from the previous frame's state and
  // marginal) and the next keyframe starts a new IMU chain.
  if (!frame.imu_from_last_frame) return;
  if (!imu_since_keyframe_) {
    imu_since_keyframe_ = std::make_shared<imu::Preintegrated>(*frame.imu_from_last_frame);
  } else {
    imu_since_keyframe_->append(*frame.imu_from_last_frame);
  }
  if (state_ == TrackingState::kLost && imu_since_keyframe_->dt_s() > options_.tracking.max_lost_imu_interval_s) {
    log::info("lost for ", imu_since_keyframe_->dt_s(), " s of IMU since the last keyframe: re-anchored at t = ",
              frame.t_s(), " s (the next keyframe starts a new IMU chain)");
    imu_since_keyframe_.reset();
    imu_chain_broken_ = true;
  }
}

SE3 Tracker::segmentAtPrediction(map::Frame& frame, const SE3& T_w_b_pred) {
  // Segmentation between the prediction and the matching (thesis Eq. 59-64): it labels the static
  // clusters the matching may use and may refine the predicted state.
  const SegmentationOutcome outcome = segment(frame, motionPrior(frame, T_w_b_pred));
  // With the IMU's prediction the pose optimisation weighs it against the features itself; the
  // dense refinement of it is the start only with Tracking.DenseStateWithImu.
  if (outcome.state_refined && (!imu_prediction_.link || options_.tracking.dense_state_with_imu)) {
    frame.setVelocity(outcome.v_w_b);
    frame.setBias(outcome.bias);
    return outcome.T_w_b;
  }
  return T_w_b_pred;
}

LossContext Tracker::lossContext(const map::Frame& frame, bool was_lost) {
  LossContext context{atlas_, state_, stats_, frame_tracked_, reference_kf_, last_kf_, last_kf_ptr_,
                      imu_since_keyframe_, imu_chain_broken_};
  context.was_lost = was_lost;
  context.min_inliers = minInliers();
  context.has_vocabulary = vocabulary_ != nullptr;
  context.imu_predicted = imu_prediction_.valid;
  context.imu_link = imu_prediction_.link.has_value();
  context.T_w_b_imu = imu_prediction_.state.T_w_b;
  context.last_tracked_t_s = last_tracked_t_s_;
  context.start_reacquire_sigma_m = startReacquireSigma(frame);
  // A lost previous frame was held at the gyroscope's rotation (Tracking.StartReacquireSpeed), so the
  // chain goes back to the last tracked frame.
  if (!imu_initialised_ && options_.tracking.gyro_rotation_gate_deg > 0.0 && frame.imu_from_last_frame &&
      last_frame_ && last_frame_->hasPose()) {
    context.gyro_R_w_b =
        normalizeRotation(prev_T_w_b_.rotationMatrix() * frame.imu_from_last_frame->correctedDeltaR(bias_));
    context.gyro_gate_rad = options_.tracking.gyro_rotation_gate_deg * M_PI / 180.0;
  }
  return context;
}

void Tracker::recordTrackedFrame(map::Frame& frame, int inliers, bool was_lost) {
  const map::Map& active = activeMap();
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    if (!isMatched(frame, i)) continue;
    if (auto point = active.mapPoint(frame.map_points[static_cast<std::size_t>(i)])) point->increaseFound();
  }
  loss_.onTrackedFrame(frame, minInliers());
  // Overlap with the reference keyframe (ORB-SLAM's measure): pose inliers over the reference
  // keyframe's established points (seen by >= 2 keyframes, >= 3 once the map has more than 2);
  // fresh single-view points do not count, so a new keyframe does not lower it by itself.
  if (auto ref = active.keyFrame(reference_kf_)) {
    const int min_observations = active.numKeyFrames() <= 2 ? 2 : 3;
    int established = 0;
    for (const map::MapPointId id : ref->mapPoints()) {
      if (!id.valid()) continue;
      const auto point = active.mapPoint(id);
      if (point && !point->isBad() && point->numObservations() >= min_observations) ++established;
    }
    stats_.overlap = established == 0 ? 1.0 : std::min(1.0, static_cast<double>(inliers) / established);
  }

  const SE3 T_w_c = frame.T_w_c();
  // The motion since the previous frame is only known when both were tracked.
  if (was_lost || stats_.relocalised) {
    velocity_T_last_cur_.reset();
    if (!imu_initialised_) frame.setVelocity(Vec3::Zero());
  } else {
    velocity_T_last_cur_ = last_frame_->T_w_c().inverse() * T_w_c;
    velocity_dt_s_ = frame.t_s() - last_frame_->t_s();
  }
  if (was_lost) resumed_without_keyframe_ = true;
  last_frame_ = frame;
  last_tracked_t_s_ = frame.t_s();
  ++frames_since_keyframe_;
  state_ = TrackingState::kOk;
  frame_tracked_ = true;
}

void Tracker::holdPrediction(map::Frame& frame, const SE3& T_w_b_pred, const Vec3& v_w_b_pred) {
  // The predicted state; with the inertial optimisation it carries the propagated information (the
  // next frame's prior), so a frame after the gap is matched in windows of its real uncertainty.
  // With the IMU it is the IMU's own prediction, not the dense solve's refinement of it: too few
  // static features matched the map to confirm that refinement, and when an occluder fills the
  // view the image term can only follow the occluder. Chained over lost frames, a refined velocity
  // that leans towards the occluder's motion would integrate into the pose (issue 10: the IMU
  // carries the pose while vision cannot).
  const bool imu_carries = imu_prediction_.valid;
  frame.setPose_T_w_b(imu_carries ? imu_prediction_.state.T_w_b : T_w_b_pred);
  frame.setVelocity(imu_carries ? imu_prediction_.state.v_w_b : v_w_b_pred);
  if (imu_carries) frame.setBias(imu_prediction_.state.bias);
  if (imu_prediction_.link) {
    frame_information_.valid = true;
    frame_information_.information = imu_prediction_.information;
  } else {
    frame_information_ = StateInformation();
  }
}

void Tracker::initialiseNewMap(map::Frame& frame) {
  last_kf_ = map::KeyFrameId();
  last_kf_ptr_.reset();
  reference_kf_ = map::KeyFrameId();
  reference_kf_ptr_.reset();
  local_keyframes_.clear();
  local_points_.clear();
  velocity_T_last_cur_.reset();
  // After the loss the velocity is the IMU's dead-reckoned one, too uncertain to be held fixed at
  // the new map's first keyframe: without a marginal the keyframe is not inertial, and the
  // keyframe link re-estimates its velocity from the next frames' poses. With
  // Tracking.NewMapVelocityPrior that estimate keeps the dead reckoning's velocity as a prior, of
  // the carried prediction's own uncertainty: the next frame alone, posed against the few points of
  // a view that just failed to track, is not enough to fix it (issue 32: plain ltlo s3, 0.7 m/s
  // off after one frame, and the dense segmentation's motion prior with it).
  new_map_velocity_kf_ = map::KeyFrameId();
  std::optional<Mat3> velocity_information;
  if (options_.tracking.new_map_velocity_prior && imu_initialised_ && frame_information_.valid) {
    const Eigen::LDLT<Mat15> ldlt(0.5 * (frame_information_.information + frame_information_.information.transpose()));
    if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
      // The propagated marginal holds the link's bias and gravity fixed: their error of the world
      // acceleration, sigma_a (as for the predicted position, tracker_inertial.cc), acts over the
      // whole loss, sigma_a t in velocity.
      const double sigma_a = std::max(options_.tracking.acc_bias_sigma_m_s2, init_acceleration_sigma_m_s2_);
      const double lost_s = std::max(0.0, frame.t_s() - last_tracked_t_s_);
      Mat3 covariance = ldlt.solve(Mat15::Identity()).block<3, 3>(6, 6) +
                        (sigma_a * lost_s) * (sigma_a * lost_s) * Mat3::Identity();
      // A map that has not tracked long enough hands on no velocity more certain than the one it
      // started with (Tracking.NewMapVelocityTrust): its least variance is raised to that sigma's.
      const double floor_m_s = loss_.velocitySigmaFloor_m_s(frame.t_s(), sigma_a);
      if (floor_m_s > 0.0) {
        const Eigen::SelfAdjointEigenSolver<Mat3> eigen(0.5 * (covariance + covariance.transpose()),
                                                        Eigen::EigenvaluesOnly);
        covariance += std::max(0.0, floor_m_s * floor_m_s - eigen.eigenvalues().minCoeff()) * Mat3::Identity();
      }
      const Eigen::LDLT<Mat3> velocity(0.5 * (covariance + covariance.transpose()));
      if (velocity.info() == Eigen::Success && velocity.isPositive() && velocity.vectorD().minCoeff() > 0.0) {
        velocity_information = velocity.solve(Mat3::Identity());
      }
    }
  }
  frame_information_ = StateInformation();
  state_ = initialise(frame);
  if (velocity_information && state_ == TrackingState::kOk && last_kf_.valid()) {
    new_map_velocity_kf_ = last_kf_;
    new_map_velocity_information_ = 0.5 * (*velocity_information + velocity_information->transpose());
    log::debug("new map's first keyframe ", last_kf_, ": velocity prior sigma ",
               std::sqrt(new_map_velocity_information_.inverse().diagonal().maxCoeff()), " m/s");
  }
}

void Tracker::recordFramePose(const map::Frame& frame) {
  prev_T_w_b_ = frame.T_w_b();
  prev_v_w_b_ = frame.v_w_b();
  prev_t_s_ = frame.t_s();
  prev_information_ = frame_information_;
  if (frame_information_.valid) {
    // The frame's own bias estimate: the next frames are preintegrated at it.
    prev_bias_ = frame.bias();
    bias_ = frame.bias();
  } else if (imu_initialised_) {
    prev_bias_ = bias_;
  }
  last_T_w_c_ = frame.T_w_c();
  if (reference_kf_ptr_) T_refb_c_last_ = reference_kf_ptr_->T_w_b().inverse() * last_T_w_c_;
}

void Tracker::refreshAfterMapChange(map::Map& map) {
  stats_.map_refreshed = true;
  if (reference_kf_ptr_) {
    const SE3 T_w_c_new = map::latestPose_T_w_b(*reference_kf_ptr_) * T_refb_c_last_;
    // The world correction of the last frame, applied to everything held in world coordinates.
    const SE3 correction = T_w_c_new * last_T_w_c_.inverse();
    const Mat3 R = correction.rotationMatrix();
    last_T_w_c_ = T_w_c_new;
    prev_T_w_b_ = correction * prev_T_w_b_;
    prev_v_w_b_ = R * prev_v_w_b_;
    if (last_frame_) {
      last_frame_->setPose_T_w_b(correction * last_frame_->T_w_b());
      last_frame_->setVelocity(R * last_frame_->v_w_b());
    }
    // The marginal's pose and bias coordinates are body-frame and unchanged; the velocity
    // perturbation is world-frame and rotates with it.
    if (prev_information_.valid) {
      Mat15 rotate = Mat15::Identity();
      rotate.block<3, 3>(6, 6) = R;
      prev_information_.information = rotate * prev_information_.information * rotate.transpose();
    }
    log::info("map ", map.id(), " changed (version ", map.version(), "): last pose moved by ",
              correction.translation().norm(), " m");
  }
  // The keyframes moved (correction or merge): the next frame links to the last keyframe.
  link_to_keyframe_ = true;
  map_id_ = map.id();
  map_version_ = map.version();
}

TrackingState Tracker::initialise(map::Frame& frame) {
  const int with_depth = staticKeypointsWithDepth(frame);
  if (with_depth < options_.min_init_features) {
    // The view is too poor to start a map (issue 32: say why, once per wait, at info level).
    if (std::isnan(init_wait_since_t_s_)) {
      init_wait_since_t_s_ = frame.t_s();
      log::info("initialisation waits at t = ", frame.t_s(), " s: the view is too poor to start a map, ", with_depth,
                " static keypoints with depth of ", frame.numKeypoints(), " keypoints (", options_.min_init_features,
                " needed); ",
                options_.tracking.pre_map_imu_pose && !first_map_started_
                    ? "the IMU keeps the pose until it starts (Tracking.PreMapImuPose)"
                    : "no pose until it starts");
    } else {
      log::debug("initialisation: ", with_depth, " static keypoints with depth, ", options_.min_init_features,
                 " needed");
    }
    return TrackingState::kNotInitialised;
  }
  if (!std::isnan(init_wait_since_t_s_)) {
    log::info("initialisation waited ", frame.t_s() - init_wait_since_t_s_, " s for a view with ", with_depth,
              " static keypoints with depth");
    init_wait_since_t_s_ = std::numeric_limits<double>::quiet_NaN();
  }
  if (!frame.hasPose()) frame.setPose_T_w_b(SE3());
  clearMatches(frame);
  map::Map& active = activeMap();
  map_id_ = active.id();
  map_version_ = active.version();
  last_T_w_c_ = frame.T_w_c();
  last_frame_ = frame;
  imu_since_keyframe_.reset();
  imu_chain_broken_ = false;
  velocity_T_last_cur_.reset();
  // Every static keypoint with depth becomes a map point (close_depth_m does not apply here).
  const double saved_close = options_.close_depth_m;
  options_.close_depth_m = std::numeric_limits<double>::infinity();
  createKeyFrame();
  options_.close_depth_m = saved_close;
  frame.map_points = last_frame_->map_points;
  frame.reference_keyframe = reference_kf_;
  last_tracked_t_s_ = frame.t_s();
  recordFramePose(frame);
  log::info("tracking initialised at t = ", frame.t_s(), " s in map ", active.id(), " with ",
            active.numMapPoints(), " map points");
  return TrackingState::kOk;
}

void Tracker::poseBeforeFirstMap(map::Frame& frame) {
  // A rest is trusted from twice the zero-velocity test's window before the first moving frame.
  const double replay_s = 2.0 * options_.zero_velocity.window_s;
  if (!pre_map_) {
    // The run's first frame: the world is its body frame.
    pre_map_.emplace(frame.t_s(), replay_s);
    pre_map_t0_s_ = frame.t_s();
  } else {
    pre_map_->propagate(frame.t_s(), frame.imu_from_last_frame ? &*frame.imu_from_last_frame : nullptr, still_);
    if (!still_ && !pre_map_->positionIntegrated() && !pre_map_position_held_logged_ &&
        frame.t_s() - pre_map_t0_s_ > replay_s) {
      pre_map_position_held_logged_ = true;
      log::info("before the first map at t = ", frame.t_s(), " s: moving with no rest seen to take gravity from, ",
                "the IMU keeps the orientation only (the position is held)");
    }
  }
  frame.setPose_T_w_b(pre_map_->T_w_b());
  frame.setVelocity(pre_map_->v_w_b());
  // Should this frame start the map, its first keyframe carries the rest's gravity and gyro bias
  // (local mapping's ImuInit.FromPreMapRest).
  if (options_.imu_init.from_pre_map_rest) frame.pre_map_rest = pre_map_->restEstimate();
  frame_posed_before_map_ = true;
}

SegmentationOutcome Tracker::segment(map::Frame& frame, const MotionPrior& prior) {
  segmentation_outcome_ = segmenter_ ? segmenter_->segment(frame, prior) : SegmentationOutcome();
  return segmentation_outcome_;
}

}  // namespace ltlo::tracking
