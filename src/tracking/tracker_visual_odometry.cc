// Tracker, part 6: visual odometry in localisation-only mode (Tracking.LocalisationOnly).
//
// Localisation only adds nothing to the loaded map, so wherever this run sees what the earlier run
// did not (another path through the room, a wall revealed behind a box), the map has no points to
// track and the pose would rest on the IMU alone, whose dead reckoning drifts by decimetres within
// seconds. As ORB-SLAM's localisation mode does, the frame is then also matched to temporary
// points: the last tracked frame's static keypoints with depth that matched no map point, placed in
// the world at that frame's pose. They are never inserted in the map; each frame replaces them.
// The pose then drifts only as frame-to-frame odometry does (millimetres per second at RGB-D
// depth noise), and the map takes over again when its points come back into view: every frame the
// odometry carries first tries the guided re-acquisition of the map (tracker_reacquire.cc) around
// its pose, within the odometry's accumulated drift.
#include <algorithm>
#include <cmath>

#include "ltlo/core/log.h"
#include "ltlo/features/matching.h"
#include "ltlo/tracking/tracker.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::isMatched;

namespace {

/// Standard deviation of the odometry's position (m) when the map last localised the frame, and
/// its growth per second of odometry (an RGB-D frame-to-frame chain at 30 Hz: ~5 mm/s measured on
/// generated runs; taken generously, the gate only has to contain the truth).
constexpr double kOdometrySigmaM = 0.02;
constexpr double kOdometrySigmaPerSecondM = 0.02;
/// The temporary points' search window, level-0 px (the last-frame search's, doubled: the
/// odometry's prediction is the IMU's or the constant-velocity model's).
constexpr double kOdometryRadiusScale = 2.0;

}  // namespace

int Tracker::trackWithOdometry(map::Frame& frame, int map_inliers) {
  stats_.odometry_inliers = 0;
  odometry_observations_.clear();
  if (map_inliers >= minInliers()) {
    last_map_localised_t_s_ = frame.t_s();
    ++frames_localised_in_map_;
    frame_map_localised_ = true;
    return map_inliers;
  }
  // Back in the map? Its points around the odometry's pose, within the odometry's drift.
  if (options_.tracking.reacquire && last_frame_) {
    const double sigma_m = kOdometrySigmaM + kOdometrySigmaPerSecondM * (frame.t_s() - last_map_localised_t_s_);
    // A search that fails leaves the frame as the map's own search left it.
    odometry_matches_before_.assign(frame.map_points.begin(), frame.map_points.end());
    odometry_outliers_before_.assign(frame.outliers.begin(), frame.outliers.end());
    const SE3 T_w_b_before = frame.T_w_b();
    const Vec3 v_w_b_before = frame.v_w_b();
    const imu::ImuBias bias_before = frame.bias();
    const StateInformation information_before = frame_information_;
    const int reacquired = reacquire(frame, T_w_b_before, sigma_m);
    if (reacquired > 0) {
      last_map_localised_t_s_ = frame.t_s();
      ++frames_localised_in_map_;
      frame_map_localised_ = true;
      return reacquired;
    }
    frame.map_points.assign(odometry_matches_before_.begin(), odometry_matches_before_.end());
    frame.outliers.assign(odometry_outliers_before_.begin(), odometry_outliers_before_.end());
    frame.setPose_T_w_b(T_w_b_before);
    frame.setVelocity(v_w_b_before);
    frame.setBias(bias_before);
    frame_information_ = information_before;
  }
  if (odometry_points_.empty()) return map_inliers;

  const SE3 T_c_w = frame.T_w_c().inverse();
  const PinholeCamera& camera = frame.camera();
  // Best temporary point per keypoint (a keypoint matched to the map keeps that match).
  std::vector<int>& best_point = odometry_best_point_;
  std::vector<int>& best_distance = odometry_best_distance_;
  best_point.assign(static_cast<std::size_t>(frame.numKeypoints()), -1);
  best_distance.assign(static_cast<std::size_t>(frame.numKeypoints()), 257);
  for (std::size_t j = 0; j < odometry_points_.size(); ++j) {
    const OdometryPoint& point = odometry_points_[j];
    const Vec3 p_c = T_c_w * point.p_w;
    if (p_c.z() <= 0.0) continue;
    const Vec2 uv = camera.project(p_c);
    if (!camera.isInImage(uv)) continue;
    const float radius = searchRadius(
        static_cast<float>(options_.last_frame_radius_px * kOdometryRadiusScale *
                           frame.scaleFactors()[static_cast<std::size_t>(point.octave)]),
        p_c.z(), camera.fx());
    for (const int i : frame.featuresInArea(static_cast<float>(uv.x()), static_cast<float>(uv.y()), radius,
                                            std::max(0, point.octave - 1), point.octave + 1)) {
      const auto k = static_cast<std::size_t>(i);
      if (!frame.isStatic(i) || isMatched(frame, i) || frame.depth_m(i) <= 0.0f) continue;
      const int d = features::hammingDistance(point.descriptor, frame.descriptors()[k]);
      if (d <= options_.max_descriptor_distance && d < best_distance[k]) {
        best_distance[k] = d;
        best_point[k] = static_cast<int>(j);
      }
    }
  }
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    const int j = best_point[static_cast<std::size_t>(i)];
    if (j < 0) continue;
    const features::Keypoint& kp = frame.keypoints()[static_cast<std::size_t>(i)];
    optim::PoseObservation observation;
    observation.p_w = odometry_points_[static_cast<std::size_t>(j)].p_w;
    observation.uv = Vec2(kp.x_px, kp.y_px);
    observation.depth_m = frame.depth_m(i);
    observation.sigma_px = std::sqrt(
        level_sigma2_[std::min<std::size_t>(static_cast<std::size_t>(kp.octave), level_sigma2_.size() - 1)]);
    observation.static_weight = frame.segmentation().gammaOf(frame.clusterOf(i));
    odometry_observations_.push_back(observation);
  }
  if (static_cast<int>(odometry_observations_.size()) < minInliers()) {
    odometry_observations_.clear();
    return map_inliers;
  }
  const int inliers = optimisePose(frame, frame.T_w_b(), false, inertialLink());
  stats_.odometry_inliers =
      static_cast<int>(std::count(odometry_inlier_.begin(), odometry_inlier_.end(), true));
  odometry_observations_.clear();
  log::debug("frame t = ", frame.t_s(), ": localisation only, ", map_inliers, " map inliers, ",
             stats_.odometry_inliers, " odometry inliers of ", odometry_inlier_.size(), " temporary matches");
  return inliers;
}

void Tracker::keepOdometryPoints(const map::Frame& frame) {
  odometry_points_.clear();
  const SE3 T_w_c = frame.T_w_c();
  for (const int i : frame.staticKeypoints()) {
    if (frame.depth_m(i) <= 0.0f || isMatched(frame, i)) continue;
    const auto k = static_cast<std::size_t>(i);
    odometry_points_.push_back(
        OdometryPoint{T_w_c * frame.p_c(i), frame.descriptors()[k], frame.keypoints()[k].octave});
  }
}

}  // namespace ltlo::tracking
