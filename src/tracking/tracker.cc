#include "ltlo/tracking/tracker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <unordered_set>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/features/matching.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/optim/pose_only_problem.h"
#include "bow/vocabulary.h"

namespace ltlo::tracking {

namespace {

/// Fewest matches before the pose is optimised (below: the search window is widened once).
constexpr int kMinMatchesToOptimise = 20;

bool isMatched(const map::Frame& frame, int i) {
  const auto k = static_cast<std::size_t>(i);
  return frame.map_points[k].valid() && !frame.outliers[k];
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

void Tracker::setImuInitialised(const imu::ImuBias& bias, const Vec3& g_w) {
  imu_initialised_ = true;
  bias_ = bias;
  g_w_ = g_w;
}

void Tracker::forceLost() {
  if (state_ != TrackingState::kNotInitialised) state_ = TrackingState::kLost;
}

namespace {

int staticKeypointsWithDepth(const map::Frame& frame) {
  int with_depth = 0;
  for (const int i : frame.staticKeypoints()) {
    if (frame.depth_m(i) > 0.0f) ++with_depth;
  }
  return with_depth;
}

void clearMatches(map::Frame& frame) {
  std::fill(frame.map_points.begin(), frame.map_points.end(), map::MapPointId());
  std::fill(frame.outliers.begin(), frame.outliers.end(), false);
}

}  // namespace

TrackingState Tracker::track(map::Frame& frame) {
  stats_ = TrackingStats();
  frame_tracked_ = false;
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

  // Accumulate the IMU since the last keyframe even across lost frames (system/ needs the chain).
  if (frame.imu_from_last_frame) {
    if (!imu_since_keyframe_) {
      imu_since_keyframe_ = *frame.imu_from_last_frame;
    } else {
      imu_since_keyframe_->append(*frame.imu_from_last_frame);
    }
  }

  const bool was_lost = state_ == TrackingState::kLost;
  SE3 T_w_b_pred = predictPose_T_w_b(frame);
  // Segmentation between the prediction and the matching (thesis Eq. 59-64): it labels the static
  // clusters the matching may use and may refine the predicted state.
  const SegmentationOutcome outcome = segment(frame, motionPrior(frame, T_w_b_pred));
  if (outcome.state_refined) {
    T_w_b_pred = outcome.T_w_b;
    frame.setVelocity(outcome.v_w_b);
    frame.setBias(outcome.bias);
  }
  const Vec3 v_w_b_pred = frame.v_w_b();
  frame.setPose_T_w_b(T_w_b_pred);
  int inliers = trackWithMotionModel(frame, T_w_b_pred);
  if (inliers < options_.min_inliers && vocabulary_ != nullptr) {
    const int relocalised = relocalise(frame);
    if (relocalised > 0) {
      inliers = relocalised;
      stats_.relocalised = true;
    }
  }
  stats_.inliers = inliers;
  frame.reference_keyframe = reference_kf_;
  if (inliers < options_.min_inliers) {
    if (state_ != TrackingState::kLost) {
      log::warn("tracking lost at t = ", frame.t_s(), " s: ", inliers, " inliers (", options_.min_inliers,
                " needed), ", frame.numKeypoints(), " keypoints");
    }
    state_ = TrackingState::kLost;
    clearMatches(frame);
    frame.setPose_T_w_b(T_w_b_pred);
    frame.setVelocity(v_w_b_pred);
    const double lost_for_s = frame.t_s() - last_tracked_t_s_;
    if (options_.new_map_after_s >= 0.0 && lost_for_s >= options_.new_map_after_s &&
        staticKeypointsWithDepth(frame) >= options_.min_init_features) {
      // New map at the predicted pose: same world frame (gravity stays valid), old map kept.
      map::Map& created = atlas_.createNewMap();
      ++maps_created_;
      log::warn("lost for ", lost_for_s, " s: new map ", created.id(), " at t = ", frame.t_s(), " s");
      last_kf_ = map::KeyFrameId();
      reference_kf_ = map::KeyFrameId();
      reference_kf_ptr_.reset();
      local_keyframes_.clear();
      local_points_.clear();
      velocity_T_last_cur_.reset();
      state_ = initialise(frame);
      LTLO_ASSERT(state_ == TrackingState::kOk, "new map not initialised");
      stats_.new_map = true;
      frame_tracked_ = true;
      return state_;
    }
    recordFramePose(frame);
    return state_;
  }
  const map::Map& active = activeMap();
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    if (!isMatched(frame, i)) continue;
    if (auto point = active.mapPoint(frame.map_points[static_cast<std::size_t>(i)])) point->increaseFound();
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
  }
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
  return state_;
}

int Tracker::trackWithMotionModel(map::Frame& frame, const SE3& T_w_b_pred) {
  // After a loss the prediction is older: search wider.
  const double radius_scale = state_ == TrackingState::kLost ? 2.0 : 1.0;
  int matches = matchLastFrame(frame, radius_scale);
  if (matches < kMinMatchesToOptimise) {
    std::fill(frame.map_points.begin(), frame.map_points.end(), map::MapPointId());
    matches = matchLastFrame(frame, 2.0 * radius_scale);
  }
  stats_.last_frame_matches = matches;
  if (matches >= kMinMatchesToOptimise) {
    stats_.last_frame_inliers = optimisePose(frame, T_w_b_pred, true);
  }
  // Local map from the frame's current matches (or the last frame's, if it matched nothing).
  updateLocalMap(stats_.last_frame_inliers >= kMinMatchesToOptimise ? frame : *last_frame_);
  stats_.local_map_matches = searchLocalMap(frame);
  int inliers = 0;
  if (stats_.local_map_matches >= kMinMatchesToOptimise) {
    inliers = optimisePose(frame, frame.T_w_b(), false);
  }
  return inliers;
}

int Tracker::relocalise(map::Frame& frame) {
  if (vocabulary_ == nullptr) return 0;
  if (!frame.hasBow()) frame.computeBow(*vocabulary_);
  map::Map& active = activeMap();
  const std::vector<RelocalisationHypothesis> hypotheses =
      relocalisationHypotheses(frame, active, atlas_.keyFrameDatabase(), options_.relocalisation);
  const map::KeyFrameId reference_before = reference_kf_;
  const std::shared_ptr<map::KeyFrame> reference_ptr_before = reference_kf_ptr_;
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
      return inliers;
    }
  }
  reference_kf_ = reference_before;
  reference_kf_ptr_ = reference_ptr_before;
  clearMatches(frame);
  return 0;
}

void Tracker::recordFramePose(const map::Frame& frame) {
  prev_T_w_b_ = frame.T_w_b();
  prev_v_w_b_ = frame.v_w_b();
  prev_t_s_ = frame.t_s();
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
    log::info("map ", map.id(), " changed (version ", map.version(), "): last pose moved by ",
              correction.translation().norm(), " m");
  }
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

SE3 Tracker::predictPose_T_w_b(map::Frame& frame) {
  if (imu_initialised_ && frame.imu_from_last_frame && state_ == TrackingState::kOk && last_kf_ptr_ &&
      !last_kf_ptr_->isBad() && imu_since_keyframe_) {
    // Map updated: when local mapping (or a correction) changed the last keyframe's pose, velocity
    // or bias, predict from the keyframe with the preintegration since it (which includes this
    // frame's samples) -- the keyframe's state is better than the last frame's.
    const SE3 T_w_b_kf = last_kf_ptr_->T_w_b();
    const Vec3 v_w_b_kf = last_kf_ptr_->v_w_b();
    const imu::ImuBias bias_kf = last_kf_ptr_->bias();
    const bool bias_changed = (bias_kf.b_a - last_kf_bias_seen_.b_a).norm() > 0.0 ||
                              (bias_kf.b_g - last_kf_bias_seen_.b_g).norm() > 0.0;
    const bool updated = (T_w_b_kf.translation() - last_kf_T_w_b_seen_.translation()).norm() > 0.0 ||
                         (T_w_b_kf.quaternion().coeffs() - last_kf_T_w_b_seen_.quaternion().coeffs()).norm() > 0.0 ||
                         (v_w_b_kf - last_kf_v_w_b_seen_).norm() > 0.0 || bias_changed;
    if (updated) {
      last_kf_T_w_b_seen_ = T_w_b_kf;
      last_kf_v_w_b_seen_ = v_w_b_kf;
      last_kf_bias_seen_ = bias_kf;
      if (bias_changed) bias_ = bias_kf;
      imu::NavState state_kf;
      state_kf.R_w_b = T_w_b_kf.rotationMatrix();
      state_kf.p_w_b = T_w_b_kf.translation();
      state_kf.v_w_b = v_w_b_kf;
      const imu::NavState state_j = imu::predict(state_kf, *imu_since_keyframe_, bias_, g_w_);
      frame.setVelocity(state_j.v_w_b);
      frame.setBias(bias_);
      stats_.used_imu = true;
      stats_.imu_from_keyframe = true;
      return SE3(Quat(normalizeRotation(state_j.R_w_b)), state_j.p_w_b);
    }
  }
  if (imu_initialised_ && frame.imu_from_last_frame) {
    // Preintegration from the previous frame's state (tracked or predicted), Forster et al. (2017)
    // eq. 26-28 through imu::predict.
    imu::NavState state_i;
    state_i.R_w_b = prev_T_w_b_.rotationMatrix();
    state_i.p_w_b = prev_T_w_b_.translation();
    state_i.v_w_b = prev_v_w_b_;
    const imu::NavState state_j = imu::predict(state_i, *frame.imu_from_last_frame, bias_, g_w_);
    frame.setVelocity(state_j.v_w_b);
    frame.setBias(bias_);
    stats_.used_imu = true;
    return SE3(Quat(normalizeRotation(state_j.R_w_b)), state_j.p_w_b);
  }
  // Constant velocity on T_w_c: the last inter-frame motion repeated, for at most max_prediction_s
  // after the last tracked frame (then the last pose is held).
  SE3 T_w_c = prev_T_w_b_ * frame.T_b_c();
  const bool keep_moving = velocity_T_last_cur_.has_value() &&
                           frame.t_s() - last_tracked_t_s_ <= options_.max_prediction_s;
  if (keep_moving) T_w_c = T_w_c * *velocity_T_last_cur_;
  frame.setVelocity(keep_moving ? prev_v_w_b_ : Vec3::Zero());
  return T_w_c * frame.T_b_c().inverse();
}

MotionPrior Tracker::motionPrior(const map::Frame& frame, const SE3& T_w_b_pred) const {
  MotionPrior prior;
  prior.T_b_c = frame.T_b_c();
  prior.T_w_b_prev = prev_T_w_b_;
  prior.v_w_b_prev = prev_v_w_b_;
  prior.bias_prev = bias_;
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

int Tracker::matchLastFrame(map::Frame& frame, double radius_scale) {
  map::Map& active = activeMap();
  const map::Frame& last = *last_frame_;
  const SE3 T_c_w = frame.T_w_c().inverse();
  const PinholeCamera& camera = frame.camera();
  features::RotationHistogram histogram;
  std::vector<std::pair<int, int>> candidates_matched;  // (current keypoint, last keypoint)
  std::vector<int> best_distance(static_cast<std::size_t>(frame.numKeypoints()), 257);
  for (int j = 0; j < last.numKeypoints(); ++j) {
    if (!isMatched(last, j)) continue;
    const auto point = active.mapPoint(last.map_points[static_cast<std::size_t>(j)]);
    if (!point || point->isBad()) continue;
    const Vec3 p_c = T_c_w * point->p_w();
    if (p_c.z() <= 0.0) continue;
    const Vec2 uv = camera.project(p_c);
    if (!camera.isInImage(uv)) continue;
    const features::Keypoint& kp_last = last.keypoints()[static_cast<std::size_t>(j)];
    const int octave = kp_last.octave;
    const float radius = static_cast<float>(options_.last_frame_radius_px * radius_scale *
                                            last.scaleFactors()[static_cast<std::size_t>(octave)]);
    const std::vector<int> area = frame.featuresInArea(static_cast<float>(uv.x()), static_cast<float>(uv.y()),
                                                       radius, std::max(0, octave - 1), octave + 1);
    const features::Descriptor& d_last = last.descriptors()[static_cast<std::size_t>(j)];
    int best = -1, best_d = 257;
    for (const int i : area) {
      if (!frame.isStatic(i)) continue;  // static features only (Seg.StaticThreshold)
      const int d = features::hammingDistance(d_last, frame.descriptors()[static_cast<std::size_t>(i)]);
      if (d < best_d) {
        best_d = d;
        best = i;
      }
    }
    if (best < 0 || best_d > options_.max_descriptor_distance) continue;
    const auto b = static_cast<std::size_t>(best);
    if (frame.map_points[b].valid() && best_distance[b] <= best_d) continue;  // keep the better one
    frame.map_points[b] = point->id();
    best_distance[b] = best_d;
    candidates_matched.emplace_back(best, j);
  }
  // Rotation consistency over the final assignment.
  std::vector<std::pair<int, int>> final_matches;
  for (const auto& [i, j] : candidates_matched) {
    if (frame.map_points[static_cast<std::size_t>(i)] == last.map_points[static_cast<std::size_t>(j)]) {
      final_matches.emplace_back(i, j);
    }
  }
  for (std::size_t k = 0; k < final_matches.size(); ++k) {
    histogram.add(last.keypoints()[static_cast<std::size_t>(final_matches[k].second)].angle_deg,
                  frame.keypoints()[static_cast<std::size_t>(final_matches[k].first)].angle_deg, static_cast<int>(k));
  }
  const std::vector<int> consistent = histogram.consistent();
  std::vector<bool> keep(final_matches.size(), false);
  for (const int k : consistent) keep[static_cast<std::size_t>(k)] = true;
  int count = 0;
  for (std::size_t k = 0; k < final_matches.size(); ++k) {
    if (keep[k]) {
      ++count;
    } else {
      frame.map_points[static_cast<std::size_t>(final_matches[k].first)] = map::MapPointId();
    }
  }
  return count;
}

int Tracker::optimisePose(map::Frame& frame, const SE3& T_w_b_init, bool drop_outliers) {
  map::Map& active = activeMap();
  optim::PoseOnlyProblem problem;
  problem.model.camera = frame.camera();
  problem.model.T_c_x = frame.T_b_c().inverse();
  problem.model.bf_px_m = options_.bf_px_m;
  problem.T_w_b_init = T_w_b_init;
  problem.v_w_b_init = frame.v_w_b();
  problem.bias_init = bias_;
  std::vector<int> index;
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (!frame.map_points[k].valid()) continue;
    const auto point = active.mapPoint(frame.map_points[k]);
    if (!point || point->isBad()) {
      frame.map_points[k] = map::MapPointId();
      continue;
    }
    optim::PoseObservation obs;
    obs.p_w = point->p_w();
    const features::Keypoint& kp = frame.keypoints()[k];
    obs.uv = Vec2(kp.x_px, kp.y_px);
    obs.depth_m = frame.depth_m(i);
    obs.sigma_px = std::sqrt(level_sigma2_[std::min<std::size_t>(static_cast<std::size_t>(kp.octave),
                                                                  level_sigma2_.size() - 1)]);
    obs.static_weight = point->beta() * frame.segmentation().gammaOf(frame.clusterOf(i));
    problem.observations.push_back(obs);
    index.push_back(i);
  }
  if (problem.observations.empty()) return 0;
  if (options_.inertial_pose_optimisation && imu_initialised_ && stats_.used_imu && frame.imu_from_last_frame) {
    optim::InertialLink link;
    link.T_w_b_prev = last_frame_->T_w_b();
    link.v_w_b_prev = last_frame_->v_w_b();
    link.bias_prev = bias_;
    link.pim = std::make_shared<const imu::Preintegrated>(*frame.imu_from_last_frame);
    link.g_w = g_w_;
    problem.inertial = link;
  }
  const optim::PoseOnlyResult result = optim::optimizePose(problem);
  frame.setPose_T_w_b(result.T_w_b);
  if (problem.inertial) {
    frame.setVelocity(result.v_w_b);
    frame.setBias(result.bias);
  } else if (last_frame_) {
    const double dt_s = frame.t_s() - last_frame_->t_s();
    if (dt_s > 0.0) {
      const Vec3 v_difference = (result.T_w_b.translation() - last_frame_->T_w_b().translation()) / dt_s;
      // With the IMU predicting, frame.v_w_b() holds the preintegrated velocity: a complementary
      // filter keeps it and corrects it slowly towards the (noisy, 0.1-0.3 m/s) finite difference.
      frame.setVelocity(stats_.used_imu ? frame.v_w_b() + options_.velocity_gain * (v_difference - frame.v_w_b())
                                        : v_difference);
    }
  }
  int inliers = 0;
  for (std::size_t k = 0; k < index.size(); ++k) {
    const auto i = static_cast<std::size_t>(index[k]);
    if (result.inliers[k]) {
      frame.outliers[i] = false;
      ++inliers;
    } else if (drop_outliers) {
      frame.map_points[i] = map::MapPointId();
      frame.outliers[i] = false;
    } else {
      frame.outliers[i] = true;
    }
  }
  return inliers;
}

void Tracker::updateLocalMap(const map::Frame& frame) {
  map::Map& active = activeMap();
  // Keyframes observing the frame's matched points, weighted by how many they share.
  std::unordered_map<map::KeyFrameId, int> counter;
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    if (!isMatched(frame, i)) continue;
    const auto point = active.mapPoint(frame.map_points[static_cast<std::size_t>(i)]);
    if (!point || point->isBad()) continue;
    for (const auto& [kf, index] : point->observations()) ++counter[kf];
  }
  local_keyframes_.clear();
  std::unordered_set<map::KeyFrameId> in_local;
  map::KeyFrameId best;
  int best_count = 0;
  for (const auto& [kf, count] : counter) {
    if (count > best_count || (count == best_count && kf < best)) {
      best_count = count;
      best = kf;
    }
  }
  std::vector<std::pair<map::KeyFrameId, int>> ordered(counter.begin(), counter.end());
  std::sort(ordered.begin(), ordered.end(), [](const auto& a, const auto& b) {
    return a.second != b.second ? a.second > b.second : a.first < b.first;
  });
  for (const auto& [kf, count] : ordered) {
    if (static_cast<int>(local_keyframes_.size()) >= options_.max_local_keyframes) break;
    if (in_local.insert(kf).second) local_keyframes_.push_back(kf);
  }
  if (best.valid()) {
    if (auto kf = active.keyFrame(best)) {
      reference_kf_ = best;
      reference_kf_ptr_ = std::move(kf);
    }
  }
  // Always include the reference keyframe and the neighbours of the first local keyframes.
  if (reference_kf_.valid() && in_local.insert(reference_kf_).second) local_keyframes_.push_back(reference_kf_);
  const std::vector<map::KeyFrameId> seeds = local_keyframes_;
  for (const map::KeyFrameId id : seeds) {
    if (static_cast<int>(local_keyframes_.size()) >= options_.max_local_keyframes) break;
    const auto kf = active.keyFrame(id);
    if (!kf) continue;
    for (const map::KeyFrameId neighbour : kf->bestCovisibles(10)) {
      if (in_local.insert(neighbour).second) {
        local_keyframes_.push_back(neighbour);
        break;  // one new neighbour per seed, as in ORB-SLAM
      }
    }
  }
  // Their points.
  local_points_.clear();
  std::unordered_set<map::MapPointId> seen;
  for (const map::KeyFrameId id : local_keyframes_) {
    const auto kf = active.keyFrame(id);
    if (!kf) continue;
    for (const map::MapPointId point : kf->mapPoints()) {
      if (point.valid() && seen.insert(point).second) local_points_.push_back(point);
    }
  }
  active.setReferenceMapPoints(local_points_);
}

int Tracker::searchLocalMap(map::Frame& frame) {
  map::Map& active = activeMap();
  std::unordered_set<map::MapPointId> already;
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    if (isMatched(frame, i)) already.insert(frame.map_points[static_cast<std::size_t>(i)]);
  }
  const SE3 T_w_c = frame.T_w_c();
  const SE3 T_c_w = T_w_c.inverse();
  const Vec3 centre_w = T_w_c.translation();
  const PinholeCamera& camera = frame.camera();
  std::vector<int> best_distance(static_cast<std::size_t>(frame.numKeypoints()), 257);
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    if (isMatched(frame, i)) best_distance[static_cast<std::size_t>(i)] = -1;  // keep last-frame matches
  }
  for (const map::MapPointId id : local_points_) {
    if (already.count(id)) continue;
    const auto point = active.mapPoint(id);
    if (!point || point->isBad()) continue;
    const Vec3 p_w = point->p_w();
    const Vec3 p_c = T_c_w * p_w;
    if (p_c.z() <= 0.0) continue;
    const Vec2 uv = camera.project(p_c);
    if (!camera.isInImage(uv)) continue;
    const Vec3 ray_w = p_w - centre_w;
    const double distance_m = ray_w.norm();
    if (point->maxDistance_m() > 0.0 &&
        (distance_m < 0.8 * point->minDistance_m() || distance_m > 1.2 * point->maxDistance_m())) {
      continue;
    }
    const Vec3 normal_w = point->normal_w();
    const double view_cos = normal_w.squaredNorm() > 0.0 ? ray_w.dot(normal_w) / distance_m : 1.0;
    if (view_cos < 0.5) continue;
    point->increaseVisible();
    const int level = point->predictScale(distance_m, frame.scaleFactors());
    const double window = view_cos > 0.998 ? 2.5 : 4.0;
    const float radius = static_cast<float>(options_.local_map_radius_px * window / 2.5 *
                                            frame.scaleFactors()[static_cast<std::size_t>(level)]);
    const std::vector<int> area = frame.featuresInArea(static_cast<float>(uv.x()), static_cast<float>(uv.y()),
                                                       radius, std::max(0, level - 1), level);
    const features::Descriptor descriptor = point->descriptor();
    int best = -1, best_d = 257, second_d = 257, best_level = -1, second_level = -1;
    for (const int i : area) {
      const auto k = static_cast<std::size_t>(i);
      if (best_distance[k] < 0) continue;  // matched to the last frame
      if (!frame.isStatic(i)) continue;    // static features only (Seg.StaticThreshold)
      const int d = features::hammingDistance(descriptor, frame.descriptors()[k]);
      const int octave = frame.keypoints()[k].octave;
      if (d < best_d) {
        second_d = best_d;
        second_level = best_level;
        best_d = d;
        best = i;
        best_level = octave;
      } else if (d < second_d) {
        second_d = d;
        second_level = octave;
      }
    }
    if (best < 0 || best_d > options_.max_descriptor_distance) continue;
    if (best_level == second_level && best_d > options_.local_map_ratio * second_d) continue;
    const auto b = static_cast<std::size_t>(best);
    if (best_d >= best_distance[b]) continue;
    frame.map_points[b] = id;
    frame.outliers[b] = false;
    best_distance[b] = best_d;
  }
  int count = 0;
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    if (isMatched(frame, i)) ++count;
  }
  return count;
}

bool Tracker::needNewKeyFrame() const {
  if (state_ != TrackingState::kOk || !last_frame_) return false;
  if (frames_since_keyframe_ < options_.min_frames_between_keyframes) return false;
  const KeyFrameOptions& kf = options_.keyframe;
  const bool interval = last_frame_->t_s() - last_keyframe_t_s_ >= kf.max_interval_s;
  const bool low_overlap = stats_.overlap < kf.max_overlap;
  const bool weak = stats_.inliers < kf.min_tracked_points;
  return (interval || low_overlap || weak) && stats_.inliers > 15;
}

std::shared_ptr<map::KeyFrame> Tracker::createKeyFrame() {
  LTLO_ASSERT(last_frame_.has_value(), "createKeyFrame() before any tracked frame");
  map::Map& active = activeMap();
  map::Frame& frame = *last_frame_;
  if (imu_since_keyframe_) frame.imu_from_last_keyframe = imu_since_keyframe_;
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
  active.updateConnections(*kf);
  if (last_kf_.valid()) {
    kf->setPreviousKeyFrame(last_kf_);
    if (const auto previous = active.keyFrame(last_kf_)) previous->setNextKeyFrame(kf->id());
    kf->setImuFromPrevious(imu_since_keyframe_);
  }
  imu_since_keyframe_.reset();
  last_kf_ = kf->id();
  last_kf_ptr_ = kf;
  last_kf_T_w_b_seen_ = kf->T_w_b();
  last_kf_v_w_b_seen_ = kf->v_w_b();
  last_kf_bias_seen_ = kf->bias();
  reference_kf_ = kf->id();
  reference_kf_ptr_ = kf;
  frame.reference_keyframe = kf->id();
  last_keyframe_t_s_ = frame.t_s();
  frames_since_keyframe_ = 0;
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
