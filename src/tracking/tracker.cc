#include "ltlo/tracking/tracker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <unordered_set>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/optim/pose_only_problem.h"
#include "bow/vocabulary.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::clearMatches;
using detail::isMatched;
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

const char* trackingStateName(TrackingState state) {
  switch (state) {
    case TrackingState::kNotInitialised: return "not-initialised";
    case TrackingState::kOk: return "ok";
    case TrackingState::kLost: return "lost";
  }
  return "?";
}

Tracker::Tracker(map::Atlas& atlas, const TrackerOptions& options, std::vector<float> level_sigma2)
    : atlas_(atlas), options_(options), level_sigma2_(std::move(level_sigma2)) {
  LTLO_ASSERT(!level_sigma2_.empty(), "the tracker needs the per-level keypoint variances");
}

void Tracker::forceLost() {
  if (state_ != TrackingState::kNotInitialised) state_ = TrackingState::kLost;
}

TrackingState Tracker::track(map::Frame& frame) {
  stats_ = TrackingStats();
  frame_tracked_ = false;
  frame_information_ = StateInformation();
  imu_prediction_ = ImuPrediction();
  if (state_ == TrackingState::kNotInitialised) {
    segment(frame, MotionPrior());
    state_ = initialise(frame);
    frame_tracked_ = state_ == TrackingState::kOk;
    return state_;
  }
  LTLO_ASSERT(last_frame_.has_value(), "tracking without a last frame");
  {
    map::Map& active = activeMap();
    if (active.id() != map_id_ || active.version() != map_version_) refreshAfterMapChange(active);
  }
  clearMatches(frame);

  // Accumulate the IMU since the last keyframe even across lost frames (system/ needs the chain),
  // O(1) per frame. While lost it is bounded: beyond max_lost_imu_interval_s it is re-anchored on
  // the predicted state (the frame-to-frame prediction goes on from the previous frame's state and
  // marginal) and the next keyframe starts a new IMU chain.
  if (frame.imu_from_last_frame) {
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

  const bool was_lost = state_ == TrackingState::kLost;
  SE3 T_w_b_pred = predictPose_T_w_b(frame);
  // Segmentation between the prediction and the matching (thesis Eq. 59-64): it labels the static
  // clusters the matching may use and may refine the predicted state.
  const SegmentationOutcome outcome = segment(frame, motionPrior(frame, T_w_b_pred));
  // With the IMU's prediction the pose optimisation weighs it against the features itself; the
  // dense refinement of it is the start only with Tracking.DenseStateWithImu.
  if (outcome.state_refined && (!imu_prediction_.link || options_.tracking.dense_state_with_imu)) {
    T_w_b_pred = outcome.T_w_b;
    frame.setVelocity(outcome.v_w_b);
    frame.setBias(outcome.bias);
  }
  const Vec3 v_w_b_pred = frame.v_w_b();
  frame.setPose_T_w_b(T_w_b_pred);
  int inliers = trackWithMotionModel(frame, T_w_b_pred);
  if (inliers < minInliers() && was_lost && options_.tracking.reacquire && imu_prediction_.link) {
    // The IMU knows roughly where the camera is: look for the map there before anything else.
    const int reacquired = reacquire(frame, imu_prediction_.state.T_w_b);
    if (reacquired > 0) {
      inliers = reacquired;
      stats_.relocalised = true;
      stats_.reacquired = true;
    }
  }
  if (inliers < minInliers() && !stats_.reacquired && vocabulary_ != nullptr) {
    const int relocalised = relocalise(frame);
    if (relocalised > 0) {
      inliers = relocalised;
      stats_.relocalised = true;
    }
  }
  stats_.inliers = inliers;
  frame.reference_keyframe = reference_kf_;
  if (inliers < minInliers()) {
    handleLostFrame(frame, T_w_b_pred, v_w_b_pred);
    return state_;
  }
  const map::Map& active = activeMap();
  int anchored_inliers = 0;
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    if (!isMatched(frame, i)) continue;
    const map::MapPointId id = frame.map_points[static_cast<std::size_t>(i)];
    if (id < carried_first_point_) ++anchored_inliers;
    if (auto point = active.mapPoint(id)) point->increaseFound();
  }
  // An open IMU-carried stretch closes when the frame matches the map from before it.
  if (carried_first_point_.valid() && anchored_inliers >= minInliers()) {
    log::info("IMU-carried stretch anchored at t = ", frame.t_s(), " s: ", anchored_inliers,
              " inliers on points older than ", carried_first_point_, " after ", frame.t_s() - anchored_t_s_, " s");
    carried_first_point_ = map::MapPointId();
  }
  if (std::isnan(tracked_run_start_s_)) tracked_run_start_s_ = frame.t_s();
  if (!carried_first_point_.valid()) {
    anchored_t_s_ = frame.t_s();
    carried_fix_t_s_ = frame.t_s();
    carried_fix_sigma_m_ = 0.0;
  } else if (frame.t_s() - tracked_run_start_s_ >= kCarriedFixSeconds) {
    carried_fix_t_s_ = frame.t_s();
    carried_fix_sigma_m_ = carried_placement_sigma_m_;
  }
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
  if (needNewKeyFrame()) {
    createKeyFrame();
    frame.map_points = last_frame_->map_points;
    frame.outliers = last_frame_->outliers;
    frame.reference_keyframe = reference_kf_;
  }
  recordFramePose(frame);
  log::debug("frame t = ", frame.t_s(), ": tracked, ", inliers, " inliers, link ", stats_.inertial_link, ", sigma ",
             stats_.predicted_position_sigma_m, " m, p = ", frame.T_w_b().translation().transpose(), ", ref ",
             reference_kf_);
  return state_;
}

void Tracker::handleLostFrame(map::Frame& frame, const SE3& T_w_b_pred, const Vec3& v_w_b_pred) {
  if (state_ != TrackingState::kLost) {
    log::warn("tracking lost at t = ", frame.t_s(), " s: ", stats_.inliers, " inliers (", minInliers(),
              " needed), ", frame.numKeypoints(), " keypoints");
  }
  state_ = TrackingState::kLost;
  tracked_run_start_s_ = std::numeric_limits<double>::quiet_NaN();
  clearMatches(frame);
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
  const double lost_for_s = frame.t_s() - last_tracked_t_s_;
  log::debug("frame t = ", frame.t_s(), ": lost, ", stats_.inliers, " inliers, link ", stats_.inertial_link,
             ", sigma ", stats_.predicted_position_sigma_m, " m, p = ", frame.T_w_b().translation().transpose(),
             ", ref ", reference_kf_);
  const int static_with_depth =
      lost_for_s >= options_.tracking.new_map_after_s ? staticKeypointsWithDepth(frame) : 0;
  const double sigma_m = imu_prediction_.link ? carried_position_sigma_m_ : std::numeric_limits<double>::infinity();
  const bool keyframe_in_map = last_kf_ptr_ && !last_kf_ptr_->isBad() && last_kf_ptr_->mapId() == activeMap().id();
  const bool can_extend = sigma_m <= options_.tracking.max_imu_position_sigma_m && keyframe_in_map &&
                          static_with_depth >= options_.tracking.min_extend_features;
  if (options_.tracking.new_map_after_s >= 0.0 && lost_for_s >= options_.tracking.new_map_after_s &&
      (can_extend || static_with_depth >= options_.min_init_features)) {
    if (can_extend) {
      // The IMU still knows where the camera is: what the frame sees is unmapped (revealed behind
      // an occluder, or new), so it extends the map at the predicted pose, linked by the IMU.
      log::warn("lost for ", lost_for_s, " s: keyframe at the IMU-predicted pose (position sigma ", sigma_m,
                " m) extends map ", activeMap().id(), " at t = ", frame.t_s(), " s");
      extendMapAtPrediction(frame);
      // The new points carry the prediction's error: the fix once frames hold them (track()).
      carried_placement_sigma_m_ = sigma_m;
      if (!carried_first_point_.valid()) {
        // The stretch opens: every point from here on was placed by the IMU.
        for (const map::MapPointId id : frame.map_points) {
          if (id.valid() && (!carried_first_point_.valid() || id < carried_first_point_)) carried_first_point_ = id;
        }
      }
      stats_.map_extended = true;
      frame_tracked_ = true;
      state_ = TrackingState::kOk;
      recordFramePose(frame);
      return;
    }
    // New map at the predicted pose: same world frame (gravity stays valid), old map kept.
    const map::MapId parent = activeMap().id();
    std::optional<map::MapOrigin> origin;
    if (imu_carries && imu_prediction_.link && std::isfinite(sigma_m)) {
      // The dead reckoning placed it in the parent's world: the loop closer may rejoin the two by
      // a search within this uncertainty (Loop.Rejoin).
      origin.emplace();
      origin->parent = parent;
      origin->sigma_position_m = sigma_m;
      origin->sigma_rotation_rad = stats_.predicted_rotation_sigma_rad;
      origin->t_s = frame.t_s();
      if (keyframe_in_map && imu_since_keyframe_ && !imu_chain_broken_) {
        // The IMU from the parent's last keyframe to this frame (the new map's first keyframe).
        origin->parent_keyframe = last_kf_;
        origin->T_w_b_parent_keyframe = last_kf_ptr_->T_w_b();
        origin->imu_across = std::make_shared<const imu::Preintegrated>(*imu_since_keyframe_);
      }
    }
    map::Map& created = atlas_.createNewMap();
    ++maps_created_;
    log::warn("lost for ", lost_for_s, " s: new map ", created.id(), " at t = ", frame.t_s(), " s");
    last_kf_ = map::KeyFrameId();
    last_kf_ptr_.reset();
    reference_kf_ = map::KeyFrameId();
    reference_kf_ptr_.reset();
    local_keyframes_.clear();
    local_points_.clear();
    velocity_T_last_cur_.reset();
    // After the loss the velocity is the IMU's dead-reckoned one, too uncertain to be held fixed at
    // the new map's first keyframe: without a marginal the keyframe is not inertial, and the
    // keyframe link re-estimates its velocity from the next frames' poses.
    frame_information_ = StateInformation();
    state_ = initialise(frame);
    LTLO_ASSERT(state_ == TrackingState::kOk, "new map not initialised");
    if (origin) {
      // Before the keyframe leaves tracking (the loop closer reads the origin with it).
      if (origin->imu_across) origin->first_keyframe = last_kf_;
      created.setOrigin(*origin);
    }
    carried_first_point_ = map::MapPointId();
    carried_fix_sigma_m_ = 0.0;
    carried_fix_t_s_ = frame.t_s();
    anchored_t_s_ = frame.t_s();
    stats_.new_map = true;
    frame_tracked_ = true;
    return;
  }
  recordFramePose(frame);
}

void Tracker::extendMapAtPrediction(map::Frame& frame) {
  clearMatches(frame);
  last_frame_ = frame;
  // Every static keypoint with depth becomes a map point (close_depth_m does not apply here).
  const double saved_close = options_.close_depth_m;
  options_.close_depth_m = std::numeric_limits<double>::infinity();
  createKeyFrame();
  options_.close_depth_m = saved_close;
  frame.map_points = last_frame_->map_points;
  frame.outliers = last_frame_->outliers;
  frame.reference_keyframe = reference_kf_;
  last_tracked_t_s_ = frame.t_s();
  velocity_T_last_cur_.reset();
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
    log::debug("initialisation: ", with_depth, " static keypoints with depth, ", options_.min_init_features,
               " needed");
    return TrackingState::kNotInitialised;
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

MotionPrior Tracker::motionPrior(const map::Frame& frame, const SE3& T_w_b_pred) const {
  MotionPrior prior;
  prior.T_b_c = frame.T_b_c();
  prior.T_w_b_prev = prev_T_w_b_;
  prior.v_w_b_prev = prev_v_w_b_;
  prior.bias_prev = imu_initialised_ ? prev_bias_ : bias_;
  if (prev_information_.valid) prior.prev_information = prev_information_.information;
  prior.T_w_b_pred = T_w_b_pred;
  prior.v_w_b_pred = frame.v_w_b();
  prior.dt_s = frame.t_s() - prev_t_s_;
  prior.g_w = g_w_;
  if (frame.imu_from_last_frame) {
    prior.pim = std::make_shared<const imu::Preintegrated>(*frame.imu_from_last_frame);
    prior.kind = imu_initialised_ ? MotionPrior::Kind::kImu : MotionPrior::Kind::kGyroConstantVelocity;
  } else if (velocity_T_last_cur_) {
    prior.kind = MotionPrior::Kind::kConstantVelocity;
  }
  return prior;
}

SegmentationOutcome Tracker::segment(map::Frame& frame, const MotionPrior& prior) {
  segmentation_outcome_ = segmenter_ ? segmenter_->segment(frame, prior) : SegmentationOutcome();
  return segmentation_outcome_;
}

bool Tracker::needNewKeyFrame() const {
  if (state_ != TrackingState::kOk || !last_frame_) return false;
  if (frames_since_keyframe_ < options_.min_frames_between_keyframes) return false;
  const KeyFrameOptions& kf = options_.keyframe;
  // Before the IMU initialisation the interval shrinks to ImuInit.MinTime / (MinKeyFrames - 1), so
  // the map can initialise the IMU as soon as MinTime of motion is covered.
  double max_interval_s = kf.max_interval_s;
  if (!imu_initialised_ && last_frame_->imu_from_last_frame && options_.imu_init_keyframe_interval_s > 0.0) {
    max_interval_s = std::min(max_interval_s, options_.imu_init_keyframe_interval_s);
  }
  const bool interval = last_frame_->t_s() - last_keyframe_t_s_ >= max_interval_s;
  const bool low_overlap = stats_.overlap < kf.max_overlap;
  // (The tolerance lets three 1/30 s frame steps count as 0.1 s.)
  constexpr double kTimeTolerance_s = 1e-6;
  const bool weak = stats_.inliers < kf.min_tracked_points &&
                    last_frame_->t_s() - last_keyframe_t_s_ >= kf.weak_min_interval_s - kTimeTolerance_s;
  // A keyframe needs enough inliers to be anchored in the map. When tracking resumes after a loss,
  // a frame tracked with the inertial optimisation is anchored by its IMU link too and needs fewer:
  // the view is then mostly unmapped, and without a keyframe its few matches run out and tracking
  // is lost again. Elsewhere (e.g. beside an occluder) such weak keyframes would crowd the local
  // window, so the vision-only rule holds.
  const int anchor_inliers =
      stats_.inertial_link != 0 && resumed_without_keyframe_ ? kf.min_inliers_inertial : kf.min_inliers;
  return (interval || low_overlap || weak) && stats_.inliers >= anchor_inliers;
}

std::shared_ptr<map::KeyFrame> Tracker::createKeyFrame() {
  LTLO_ASSERT(last_frame_.has_value(), "createKeyFrame() before any tracked frame");
  map::Map& active = activeMap();
  map::Frame& frame = *last_frame_;
  // The IMU since the last keyframe is this keyframe's link, unless it was re-anchored while lost.
  std::optional<imu::Preintegrated> imu_link;
  if (imu_since_keyframe_ && !imu_chain_broken_) imu_link = *imu_since_keyframe_;
  if (imu_link) frame.imu_from_last_keyframe = imu_link;
  // Keyframes need their BoW for the database (relocalisation, loops, merges).
  if (vocabulary_ != nullptr && !frame.hasBow()) frame.computeBow(*vocabulary_);
  const std::shared_ptr<map::KeyFrame> kf = active.createKeyFrame(frame);
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (!frame.map_points[k].valid()) continue;
    if (frame.outliers[k]) {
      frame.map_points[k] = map::MapPointId();
      frame.outliers[k] = false;
      continue;
    }
    const auto point = active.mapPoint(frame.map_points[k]);
    if (!point || !active.addObservation(*kf, i, *point)) {
      frame.map_points[k] = map::MapPointId();
      continue;
    }
    active.updateNormalAndDistances(*point);
    active.updateDescriptor(*point);
  }
  const int created = addNewMapPoints(*kf, frame);
  if (last_kf_.valid()) {
    kf->setPreviousKeyFrame(last_kf_);
    if (const auto previous = active.keyFrame(last_kf_)) previous->setNextKeyFrame(kf->id());
    kf->setImuFromPrevious(std::move(imu_link));
  }
  active.updateConnections(*kf);  // after the chain link: it is the parent of last resort
  imu_since_keyframe_.reset();
  imu_chain_broken_ = false;
  link_to_keyframe_ = true;
  last_kf_ = kf->id();
  last_kf_ptr_ = kf;
  last_kf_T_w_b_seen_ = kf->T_w_b();
  last_kf_v_w_b_seen_ = kf->v_w_b();
  // Its velocity is an inertial estimate when the frame's state came from the IMU (the
  // pose-inertial optimisation or, lost, the IMU prediction); else local mapping will set it.
  last_kf_inertial_ = imu_initialised_ && frame_information_.valid;
  last_kf_bias_seen_ = kf->bias();
  reference_kf_ = kf->id();
  reference_kf_ptr_ = kf;
  frame.reference_keyframe = kf->id();
  last_keyframe_t_s_ = frame.t_s();
  frames_since_keyframe_ = 0;
  resumed_without_keyframe_ = false;
  ++num_keyframes_;
  log::debug("keyframe ", kf->id(), " at t = ", frame.t_s(), " s: ", kf->numObservations(), " points (", created,
             " new)");
  if (local_mapping_) local_mapping_(active, kf);
  return kf;
}

int Tracker::addNewMapPoints(map::KeyFrame& kf, map::Frame& frame) {
  map::Map& active = activeMap();
  std::vector<std::pair<float, int>> by_depth;
  for (const int i : frame.staticKeypoints()) {
    const float depth = frame.depth_m(i);
    if (depth > 0.0f && !frame.map_points[static_cast<std::size_t>(i)].valid()) by_depth.emplace_back(depth, i);
  }
  std::sort(by_depth.begin(), by_depth.end());
  const SE3 T_w_c = frame.T_w_c();
  int created = 0;
  for (const auto& [depth, i] : by_depth) {
    if (depth > options_.close_depth_m && created >= options_.min_new_points) break;
    const auto point = active.createMapPoint(T_w_c * frame.p_c(i), kf.id());
    if (!active.addObservation(kf, i, *point)) {
      active.eraseMapPoint(point->id());
      continue;
    }
    active.updateNormalAndDistances(*point);
    active.updateDescriptor(*point);
    frame.map_points[static_cast<std::size_t>(i)] = point->id();
    ++created;
  }
  return created;
}

}  // namespace ltlo::tracking