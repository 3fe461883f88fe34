// Tracker, part 6 (issue 32): standstill. The IMU's zero-velocity test on every frame; while it says
// rest, the zero-velocity update holds the pose, the velocity (zero) and the biases, keyframes are
// not made (boxes moving through the view would lower the overlap again and again), and at a still
// start one keyframe at rest lets local mapping initialise the IMU from the standstill.
#include <algorithm>
#include <vector>

#include "ltlo/core/log.h"
#include "ltlo/tracking/tracker.h"
#include "tracker_util.h"

namespace ltlo::tracking {

namespace {

// Standard deviation of the velocity of a body at rest in the state prior of a held frame (m/s):
// the robot's residual vibration at a standstill, far below what a frame of motion gives.
constexpr double kRestVelocitySigma_m_s = 1e-3;
// A held frame without a marginal of its own gets this prior (the state at the stop's start is as
// known as a tracked frame's; the biases are left loose for the next optimisations).
constexpr double kHeldRotationSigma_rad = 2e-3, kHeldPositionSigma_m = 2e-3;
constexpr double kHeldGyroBiasSigma_rad_s = 1e-2, kHeldAccBiasSigma_m_s2 = 0.1;
// Static matches the visual check needs before it has a say.
constexpr int kMinVisualCheckMatches = 10;

}  // namespace

void Tracker::updateStandstill(const map::Frame& frame) {
  // Tracking.PreMapImuPose needs the test only until the first map starts (its rest holds the pose).
  const bool pre_map = options_.tracking.pre_map_imu_pose && !first_map_started_;
  if (!(options_.zero_velocity_test || pre_map) || frame.imu_samples.empty()) {
    still_ = false;
    return;
  }
  if (!zero_velocity_) zero_velocity_.emplace(options_.zero_velocity);
  const bool was_still = still_;
  const Vec3 b_g = imu_initialised_ ? bias_.b_g : Vec3::Zero();
  still_ = zero_velocity_->update(frame.imu_samples, b_g);
  if (still_ && !was_still) {
    still_from_t_s_ = zero_velocity_->windowStart_s();
    still_bias_ = imu_initialised_ ? prev_bias_ : bias_;
    log::info("standstill from t = ", frame.t_s(), " s (zero-velocity test: gyro ",
              zero_velocity_->statistics().gyro_ratio, ", acc ", zero_velocity_->statistics().acc_ratio,
              " of the noise)");
  } else if (!still_ && was_still) {
    log::info("moving again at t = ", frame.t_s(), " s");
  }
}

bool Tracker::holdingStill() const {
  return options_.tracking.zupt && still_ && state_ != TrackingState::kNotInitialised;
}

bool Tracker::stillConfirmedByView(const map::Frame& frame) {
  if (!options_.tracking.zupt_visual_check) return true;
  const map::Map& active = activeMap();
  const SE3 T_c_w = (prev_T_w_b_ * frame.T_b_c()).inverse();
  std::vector<double> errors_px;
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (!frame.map_points[k].valid() || frame.outliers[k] || !frame.isStatic(i)) continue;
    const auto point = active.mapPoint(frame.map_points[k]);
    if (!point || point->isBad()) continue;
    const Vec3 p_c = T_c_w * point->p_w();
    if (p_c.z() <= 0.0) continue;
    const Vec2 uv = frame.camera().project(p_c);
    const features::Keypoint& kp = frame.keypoints()[k];
    errors_px.push_back((uv - Vec2(kp.x_px, kp.y_px)).norm());
  }
  if (static_cast<int>(errors_px.size()) < kMinVisualCheckMatches) return true;
  const auto middle = errors_px.begin() + static_cast<std::ptrdiff_t>(errors_px.size() / 2);
  std::nth_element(errors_px.begin(), middle, errors_px.end());
  const bool confirmed = *middle <= options_.tracking.zupt_max_displacement_px;
  if (!confirmed) {
    log::debug("frame t = ", frame.t_s(), ": the IMU says rest, ", errors_px.size(),
               " static matches disagree (median ", *middle, " px at the held pose)");
  }
  return confirmed;
}

bool Tracker::restKeyFrameDue(const map::Frame& frame) const {
  // The whole IMU link since the last keyframe must be a standstill: the window that first said
  // rest reaches back to the keyframe.
  const double tolerance_s = 2.0 / options_.zero_velocity.rate_hz;
  return options_.rest_keyframe && !imu_initialised_ && !rest_keyframe_made_ && last_kf_ptr_ &&
         imu_since_keyframe_ && !imu_chain_broken_ && still_from_t_s_ <= last_keyframe_t_s_ + tolerance_s &&
         frame.t_s() - last_keyframe_t_s_ >= options_.rest_time_s;
}

TrackingState Tracker::trackStill(map::Frame& frame, int inliers, bool was_lost) {
  frame.setPose_T_w_b(prev_T_w_b_);
  frame.setVelocity(Vec3::Zero());
  frame.setBias(still_bias_);
  // The held state is as well known as the stop's first frame; its velocity is known to be zero.
  if (!frame_information_.valid) frame_information_ = prev_information_;
  if (!frame_information_.valid) {
    Vec15 sigma;
    sigma << Vec3::Constant(kHeldRotationSigma_rad), Vec3::Constant(kHeldPositionSigma_m),
        Vec3::Constant(kRestVelocitySigma_m_s), Vec3::Constant(kHeldGyroBiasSigma_rad_s),
        Vec3::Constant(kHeldAccBiasSigma_m_s2);
    frame_information_.valid = true;
    frame_information_.information = sigma.cwiseInverse().cwiseAbs2().asDiagonal();
  }
  frame_information_.information.block<3, 3>(6, 6) +=
      Mat3::Identity() / (kRestVelocitySigma_m_s * kRestVelocitySigma_m_s);
  stats_.inliers = inliers;
  recordTrackedFrame(frame, inliers, was_lost);
  link_last_frame_after_rest_ = true;
  if (restKeyFrameDue(frame)) {
    last_frame_->at_rest = true;
    frame.at_rest = true;
    createKeyFrame();
    rest_keyframe_made_ = true;
    frame.map_points = last_frame_->map_points;
    frame.outliers = last_frame_->outliers;
    frame.reference_keyframe = reference_kf_;
    log::info("keyframe at rest at t = ", frame.t_s(), " s for the IMU initialisation from rest");
  }
  recordFramePose(frame);
  return state_;
}

}  // namespace ltlo::tracking
