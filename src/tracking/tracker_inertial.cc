// Tracker, part 3: the motion prediction (IMU or constant velocity) and the segmentation step's
// motion prior from it, the inertial link of the pose-inertial optimisation (last keyframe or last
// frame with its marginal as a prior) and the pose optimisation itself.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "ltlo/core/log.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/optim/pose_only_problem.h"
#include "ltlo/tracking/tracker.h"

namespace ltlo::tracking {

namespace {

/// Position sigma along the least constrained direction of a pose's marginal information
/// [dphi; drho] (rho in the body frame, so its norm is the world's), m; infinity when singular.
double positionSigma_m(const Mat6& pose_information) {
  const Eigen::LDLT<Mat6> ldlt(0.5 * (pose_information + pose_information.transpose()));
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || pose_information.isZero()) {
    return std::numeric_limits<double>::infinity();
  }
  const Mat3 covariance = ldlt.solve(Mat6::Identity()).block<3, 3>(3, 3);
  const double largest = Eigen::SelfAdjointEigenSolver<Mat3>(0.5 * (covariance + covariance.transpose())).eigenvalues().maxCoeff();
  return largest > 0.0 ? std::sqrt(largest) : std::numeric_limits<double>::infinity();
}

/// Chi2 of the velocity's move from the dead-reckoned prediction above which a new map's velocity
/// prior is dropped (Tracking.NewMapVelocityPrior): the 95 % test of 3 DoF, as for an observation.
constexpr double kNewMapVelocityChi2 = optim::kChi2Threshold3Dof;

bool sameState(const SE3& a, const SE3& b) {
  return (a.translation() - b.translation()).norm() == 0.0 &&
         (a.quaternion().coeffs() - b.quaternion().coeffs()).norm() == 0.0;
}

double largestSigma(const Mat3& covariance) {
  const Eigen::SelfAdjointEigenSolver<Mat3> eigen(0.5 * (covariance + covariance.transpose()), Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
}

}  // namespace

std::optional<Mat15> Tracker::stateInformation() const {
  if (!prev_information_.valid) return std::nullopt;
  return prev_information_.information;
}

void Tracker::setImuInitialised(const imu::ImuBias& bias, const Vec3& g_w, double acceleration_sigma_m_s2,
                                bool early_keyframes) {
  if (velocity_unknown_) {
    // A run in a loaded atlas: applied once the velocity is (tracker_loaded_start.cc).
    deferred_imu_ = DeferredImu{bias, g_w, acceleration_sigma_m_s2};
    return;
  }
  imu_initialised_ = true;
  early_keyframes_after_init_ = early_keyframes;
  init_acceleration_sigma_m_s2_ = acceleration_sigma_m_s2;
  bias_ = bias;
  prev_bias_ = bias;
  still_bias_ = bias;  // a frame held at rest keeps the new estimate from now on
  g_w_ = g_w;
  // New gravity and biases (first initialisation or a refinement, with the keyframes' velocities
  // re-estimated): the next frame links to the last keyframe instead of the old marginal.
  link_to_keyframe_ = true;
  prev_information_ = StateInformation();
}

const optim::InertialLink* Tracker::inertialLink() const {
  return imu_prediction_.link ? &*imu_prediction_.link : nullptr;
}

int Tracker::minInliers() const {
  return inertialLink() != nullptr ? options_.tracking.min_inliers_imu : options_.tracking.min_inliers;
}

SE3 Tracker::predictPose_T_w_b(map::Frame& frame) {
  if (imu_initialised_ && frame.imu_from_last_frame) {
    imu_prediction_ = predictWithImu(frame);
    frame.setVelocity(imu_prediction_.state.v_w_b);
    frame.setBias(imu_prediction_.state.bias);
    stats_.used_imu = true;
    stats_.imu_from_keyframe = imu_prediction_.link_kind == 1;
    if (imu_prediction_.link) {
      stats_.inertial_link = imu_prediction_.link_kind;
      // Standard deviations of the prediction for the search windows: the camera centre moves with
      // the body position and, through the lever arm T_b_c, with its rotation.
      const Eigen::LDLT<Mat15> ldlt(imu_prediction_.information);
      if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
        const Mat15 covariance = ldlt.solve(Mat15::Identity());
        const double sigma_r = largestSigma(covariance.block<3, 3>(0, 0));
        // The keyframe's bias and gravity are held fixed by the links: the error of the world
        // acceleration they give acts over the time since the last tracked frame, 0.5 sigma_a t^2,
        // independent of the filter's. sigma_a is the (re)initialisation's own posterior
        // uncertainty, at least Tracking.AccBiasSigma.
        const double sigma_a =
            std::max(options_.tracking.acc_bias_sigma_m_s2, init_acceleration_sigma_m_s2_);
        const double gap_s = frame.t_s() - last_tracked_t_s_;
        const double bias_drift_m = 0.5 * sigma_a * gap_s * gap_s;
        const double sigma_p = largestSigma(covariance.block<3, 3>(3, 3));
        const double lever_m = sigma_r * frame.T_b_c().translation().norm();
        stats_.predicted_rotation_sigma_rad = sigma_r;
        // At least the velocity sigma of a map not yet trusted to hand on its own (loss_recovery.h).
        stats_.predicted_velocity_sigma_m_s =
            std::max(std::hypot(largestSigma(covariance.block<3, 3>(6, 6)), sigma_a * gap_s),
                     loss_.velocitySigmaFloor_m_s(frame.t_s(), sigma_a));
        stats_.predicted_position_sigma_m = std::hypot(sigma_p, bias_drift_m) + lever_m;
        // The loss policy's sigma, over an IMU-carried stretch from its last visual fix.
        loss_.updateCarriedSigma(frame.t_s(), sigma_p, sigma_a, bias_drift_m, lever_m);
      }
    }
    return imu_prediction_.state.T_w_b;
  }
  // Constant velocity on T_w_c: the last inter-frame motion repeated, for at most max_prediction_s
  // after the last tracked frame (then the last pose is held).
  SE3 T_w_c = prev_T_w_b_ * frame.T_b_c();
  const bool keep_moving = velocity_T_last_cur_.has_value() &&
                           frame.t_s() - last_tracked_t_s_ <= options_.max_prediction_s;
  if (keep_moving) {
    // The motion of the last interval, scaled to this one's length where they differ (a dropped
    // frame doubles it); evenly spaced frames (stamps within 1 %) repeat it exactly.
    const double dt_s = frame.t_s() - prev_t_s_;
    const double ratio = velocity_dt_s_ > 0.0 && dt_s > 0.0 ? dt_s / velocity_dt_s_ : 1.0;
    T_w_c = std::abs(ratio - 1.0) <= 0.01 ? T_w_c * *velocity_T_last_cur_
                                          : T_w_c * SE3::exp(ratio * velocity_T_last_cur_->log());
  }
  frame.setVelocity(keep_moving ? prev_v_w_b_ : Vec3::Zero());
  const SE3 T_w_b_pred = startGyroRotation(frame, T_w_c * frame.T_b_c().inverse());
  if (options_.tracking.start_carried_lost && state_ == TrackingState::kLost && !imu_initialised_ &&
      options_.tracking.start_reacquire_speed_m_s > 0.0 && frame.imu_from_last_frame) {
    start_predicted_T_w_b_ = T_w_b_pred;
  }
  return T_w_b_pred;
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

Tracker::ImuPrediction Tracker::predictWithImu(const map::Frame& frame) {
  ImuPrediction out;
  out.valid = true;
  const bool optimise = options_.tracking.inertial_pose_optimisation;

  // The last keyframe as the link's start: usable when it is live in the active map and the IMU
  // since it is one chain. Local mapping (or a correction) changing its state is the "map updated"
  // case: its state is then better than the last frame's (ORB-SLAM3's map-updated prediction).
  const bool keyframe_usable = last_kf_ptr_ && !last_kf_ptr_->isBad() && imu_since_keyframe_ && !imu_chain_broken_ &&
                               last_kf_ptr_->mapId() == activeMap().id();
  bool keyframe_updated = false;
  SE3 T_w_b_kf;
  Vec3 v_w_b_kf = Vec3::Zero();
  imu::ImuBias bias_kf;
  if (keyframe_usable) {
    T_w_b_kf = last_kf_ptr_->T_w_b();
    v_w_b_kf = last_kf_ptr_->v_w_b();
    bias_kf = last_kf_ptr_->bias();
    const bool bias_changed = (bias_kf.b_a - last_kf_bias_seen_.b_a).norm() > 0.0 ||
                              (bias_kf.b_g - last_kf_bias_seen_.b_g).norm() > 0.0;
    const bool velocity_changed = (v_w_b_kf - last_kf_v_w_b_seen_).norm() > 0.0;
    keyframe_updated = !sameState(T_w_b_kf, last_kf_T_w_b_seen_) || velocity_changed || bias_changed;
    // Local mapping writes keyframe velocities only from the IMU (initialisation, VI-BA), and
    // biases with them.
    if (velocity_changed && imu_initialised_) last_kf_inertial_ = true;
    if (keyframe_updated) {
      last_kf_T_w_b_seen_ = T_w_b_kf;
      last_kf_v_w_b_seen_ = v_w_b_kf;
      last_kf_bias_seen_ = bias_kf;
      if (bias_changed && last_kf_inertial_) bias_ = bias_kf;
    }
  }
  // Without the inertial optimisation (the ablation) the keyframe only restarts the prediction
  // when local mapping updated it while tracking; with it, also right after a keyframe, a map
  // change or an IMU (re)initialisation, and whenever the last frame has no marginal. At rest and
  // on the frame after, an update of the keyframe from before the stop does not restart it: the
  // held frame's state and its rest prior are better than a link through the whole standstill.
  const bool from_keyframe =
      keyframe_usable &&
      (optimise ? ((keyframe_updated && !link_last_frame_after_rest_) || link_to_keyframe_ || !prev_information_.valid)
                                   : (keyframe_updated && state_ == TrackingState::kOk));

  optim::InertialLink link;
  link.g_w = g_w_;
  if (from_keyframe) {
    // The keyframe's state is held fixed; the preintegration since it includes this frame.
    link.T_w_b_prev = T_w_b_kf;
    link.v_w_b_prev = v_w_b_kf;
    link.pim = imu_since_keyframe_;
    // A keyframe from before the IMU initialisation (not yet updated by local mapping) has a
    // vision-only (finite-difference) velocity and no bias: its velocity is estimated here from the
    // keyframe's and this frame's poses, and the initialisation's bias is used.
    link.bias_prev = last_kf_inertial_ ? bias_kf : bias_;
    link.prev_velocity_free = !last_kf_inertial_;
    if (link.prev_velocity_free && new_map_velocity_kf_.valid() && new_map_velocity_kf_ == last_kf_) {
      link.prev_velocity_information = new_map_velocity_information_;  // Tracking.NewMapVelocityPrior
    }
    out.link_kind = 1;
  } else {
    // The previous frame (tracked or predicted) with the marginal of its own optimisation (or of
    // its prediction); without one (rare: no usable keyframe after a reset) its state is held.
    link.T_w_b_prev = prev_T_w_b_;
    link.v_w_b_prev = prev_v_w_b_;
    link.bias_prev = optimise ? prev_bias_ : bias_;
    link.pim = std::make_shared<const imu::Preintegrated>(*frame.imu_from_last_frame);
    if (prev_information_.valid) link.prev_prior = optim::PreviousStatePrior{prev_information_.information};
    out.link_kind = 2;
  }
  // Preintegration from the link's start, Forster et al. (2017) eq. 26-28 through imu::predict.
  const imu::NavState predicted =
      imu::predict(imu::navState(link.T_w_b_prev, link.v_w_b_prev), *link.pim, link.bias_prev, g_w_);
  out.state.T_w_b = SE3(Quat(normalizeRotation(predicted.R_w_b)), predicted.p_w_b);
  out.state.v_w_b = predicted.v_w_b;
  out.state.bias = link.bias_prev;
  if (optimise) {
    out.information = optim::predictedStateInformation(link, out.state);
    out.link = std::move(link);
  }
  link_to_keyframe_ = false;
  return out;
}

int Tracker::optimisePose(map::Frame& frame, const SE3& T_w_b_init, bool drop_outliers,
                          const optim::InertialLink* link) {
  map::Map& active = activeMap();
  optim::PoseOnlyProblem problem;
  problem.model.camera = frame.camera();
  problem.model.T_c_x = frame.T_b_c().inverse();
  problem.model.bf_px_m = frame.camera().fx() * options_.tracking.virtual_baseline_m;
  problem.T_w_b_init = T_w_b_init;
  problem.v_w_b_init = frame.v_w_b();
  problem.bias_init = imu_initialised_ ? frame.bias() : bias_;
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
  // Localisation only: the matches to the last frame's temporary points (trackWithOdometry).
  const std::size_t num_map_observations = problem.observations.size();
  problem.observations.insert(problem.observations.end(), odometry_observations_.begin(),
                              odometry_observations_.end());
  if (problem.observations.empty() && link == nullptr) return 0;
  if (link != nullptr) problem.inertial = *link;
  optim::PoseOnlyResult result = optim::optimizePose(problem);
  if (problem.inertial && problem.inertial->prev_velocity_information && imu_prediction_.valid) {
    // Tracking.NewMapVelocityPrior: the prior is the dead reckoning's velocity, whose marginal
    // says nothing of how well the frames before the loss knew it. When the frame's observations
    // move the velocity away from the prediction by more than that marginal allows (chi2 test,
    // 3 DoF, 95 %), the dead-reckoned velocity is wrong: the link leaves it free as without the
    // switch.
    const Eigen::LDLT<Mat15> ldlt(0.5 * (imu_prediction_.information + imu_prediction_.information.transpose()));
    if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
      const Mat3 covariance = ldlt.solve(Mat15::Identity()).block<3, 3>(6, 6);
      const Vec3 dv = result.v_w_b - imu_prediction_.state.v_w_b;
      const double chi2 = dv.dot(covariance.ldlt().solve(dv));
      log::debug("frame t = ", frame.t_s(), ": new map's velocity prior, chi2 ", chi2, " (", result.num_inliers,
                 " inliers), dv = ", dv.transpose());
      if (!(chi2 <= kNewMapVelocityChi2)) {
        problem.inertial->prev_velocity_information.reset();
        result = optim::optimizePose(problem);
      }
    }
  }
  frame.setPose_T_w_b(result.T_w_b);
  // Only Tracking.StartMotionCheck reads it, and only before the IMU is initialised.
  if (!imu_initialised_ && options_.tracking.start_motion_check_m_s2 > 0.0) {
    pose_sigma_m_ = positionSigma_m(result.pose_information);
  }
  if (problem.inertial) {
    // Velocity and biases from the pose-inertial optimisation; its marginal is the next frame's
    // prior.
    frame.setVelocity(result.v_w_b);
    frame.setBias(result.bias);
    frame_information_.valid = true;
    frame_information_.information = result.state_information;
  } else if (last_frame_ && (!imu_initialised_ || !options_.tracking.inertial_pose_optimisation)) {
    // Vision only: before the IMU is initialised, or the ablation without the inertial
    // optimisation (with it, a vision-only pose here is a relocalisation hypothesis and keeps the
    // predicted velocity).
    frame_information_ = StateInformation();
    const double dt_s = frame.t_s() - last_frame_->t_s();
    if (dt_s > 0.0) {
      const Vec3 v_difference = (result.T_w_b.translation() - last_frame_->T_w_b().translation()) / dt_s;
      // With the IMU predicting, frame.v_w_b() holds the preintegrated velocity: a complementary
      // filter keeps it and corrects it slowly towards the (noisy, 0.1-0.3 m/s) finite difference.
      frame.setVelocity(stats_.used_imu ? frame.v_w_b() + options_.velocity_gain * (v_difference - frame.v_w_b())
                                        : v_difference);
    }
  } else {
    frame_information_ = StateInformation();
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
  odometry_inlier_.assign(odometry_observations_.size(), false);
  for (std::size_t k = 0; k < odometry_observations_.size(); ++k) {
    odometry_inlier_[k] = result.inliers[num_map_observations + k];
    if (odometry_inlier_[k]) ++inliers;
  }
  return inliers;
}

}  // namespace ltlo::tracking
