// Tracker, part 4: guided re-acquisition of the active map by a lost frame after an IMU-only
// stretch (Tracking.Reacquire). When vision comes back after seconds of IMU dead-reckoning, the
// predicted pose is off by more than the usual search windows allow (0.5 sigma_a t^2: 0.24 m after
// 4 s at 0.03 m/s^2), and the map around it may no longer be the local map of the last tracked
// frame. The map points of the keyframes around the predicted pose are projected with it and
// matched to the frame's static keypoints with depth in windows of the predicted reprojection's
// uncertainty; a 3-D-3-D RANSAC pose (depth on both sides) must agree with the prediction within
// Tracking.ReacquireGateSigmas of its standard deviation, and is then refined like a
// relocalisation (pose optimisation, local-map search, the IMU link to the previous frame).
#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "ltlo/core/log.h"
#include "ltlo/features/matching.h"
#include "ltlo/loop/se3_ransac.h"
#include "ltlo/tracking/tracker.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::clearMatches;
using detail::staticKeypointsWithDepth;

namespace {

/// A keyframe looking the same way as the predicted camera (optical axes within 60 degrees) may
/// share points with it; the nearest of them form the re-acquisition's map.
constexpr double kMinAxisCosine = 0.5;

/// Ratio test of the wide-window matching: a window of k sigma holds most of the frame's static
/// keypoints, so the second best is the best of many random descriptors; the RANSAC and the gate
/// remove what the looser test lets through.
constexpr double kReacquireRatio = 0.9;
/// RANSAC draws: with the looser ratio test a fifth of the matches may be right; 1000 draws of three
/// find an all-inlier sample with probability 1 - (1 - 0.2^3)^1000 > 0.999.
constexpr int kReacquireRansacIterations = 1000;

/// Angle of the rotation between two camera poses (rad).
double rotationAngle_rad(const SE3& a, const SE3& b) {
  return so3Log(a.quaternion().conjugate() * b.quaternion()).norm();
}

struct Candidate {
  int keypoint = -1;
  map::MapPointId point;
  Vec3 p_w = Vec3::Zero();
  int distance = 257;
};

}  // namespace

int Tracker::reacquire(map::Frame& frame, const SE3& T_w_b_pred) {
  const TrackingOptions& o = options_.tracking;
  const double sigma_p = carried_position_sigma_m_;
  const double sigma_r = stats_.predicted_rotation_sigma_rad;
  if (!std::isfinite(sigma_p) || staticKeypointsWithDepth(frame) < o.reacquire_min_inliers) return 0;
  map::Map& active = activeMap();
  const SE3 T_w_c_pred = T_w_b_pred * frame.T_b_c();
  const SE3 T_c_w_pred = T_w_c_pred.inverse();
  const Vec3 centre_w = T_w_c_pred.translation();
  const Vec3 axis_w = T_w_c_pred.quaternion() * Vec3::UnitZ();

  // The keyframes around the prediction, nearest first.
  std::vector<std::pair<double, std::shared_ptr<map::KeyFrame>>> nearby;
  for (std::shared_ptr<map::KeyFrame>& kf : active.keyFrames()) {
    if (!kf || kf->isBad()) continue;
    const SE3 T_w_c = kf->T_w_c();
    if ((T_w_c.quaternion() * Vec3::UnitZ()).dot(axis_w) < kMinAxisCosine) continue;
    nearby.emplace_back((T_w_c.translation() - centre_w).norm(), std::move(kf));
  }
  std::sort(nearby.begin(), nearby.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second->id() < b.second->id();
  });
  if (static_cast<int>(nearby.size()) > options_.max_local_keyframes) nearby.resize(options_.max_local_keyframes);

  // Projection of their points with the prediction; static keypoints with depth within the
  // window, best descriptor with the ratio test, each keypoint kept for its best point.
  const PinholeCamera& camera = frame.camera();
  std::vector<Candidate> best(static_cast<std::size_t>(frame.numKeypoints()));
  std::unordered_set<map::MapPointId> seen;
  int considered = 0, projected = 0, with_candidate = 0, below_distance = 0;
  for (const auto& [distance_kf_m, kf] : nearby) {
    for (const map::MapPointId id : kf->mapPoints()) {
      if (!id.valid() || !seen.insert(id).second) continue;
      const auto point = active.mapPoint(id);
      if (!point || point->isBad()) continue;
      ++considered;
      const Vec3 p_w = point->p_w();
      const Vec3 p_c = T_c_w_pred * p_w;
      if (p_c.z() <= 0.1) continue;
      const Vec2 uv = camera.project(p_c);
      if (!camera.isInImage(uv)) continue;
      ++projected;
      const double distance_m = (p_w - centre_w).norm();
      const int level = point->predictScale(distance_m, frame.scaleFactors());
      // Reprojection standard deviation under the predicted uncertainty (as searchRadius).
      const double sigma_px = camera.fx() * (sigma_p / p_c.z() + sigma_r);
      const double radius_px =
          std::clamp(o.reacquire_gate_sigmas * sigma_px, options_.local_map_radius_px, o.reacquire_max_radius_px) *
          frame.scaleFactors()[static_cast<std::size_t>(level)];
      const std::vector<int> area = frame.featuresInArea(static_cast<float>(uv.x()), static_cast<float>(uv.y()),
                                                         static_cast<float>(radius_px), std::max(0, level - 1),
                                                         level + 1);
      const features::Descriptor descriptor = point->descriptor();
      int best_i = -1, best_d = 257, second_d = 257;
      for (const int i : area) {
        if (!frame.isStatic(i) || frame.depth_m(i) <= 0.0f) continue;
        const int d = features::hammingDistance(descriptor, frame.descriptors()[static_cast<std::size_t>(i)]);
        if (d < best_d) {
          second_d = best_d;
          best_d = d;
          best_i = i;
        } else if (d < second_d) {
          second_d = d;
        }
      }
      // Wide windows: the tracker's projection threshold and a loose ratio test.
      if (best_i < 0) continue;
      ++with_candidate;
      if (best_d > options_.max_descriptor_distance) continue;
      ++below_distance;
      if (best_d > kReacquireRatio * second_d) continue;
      Candidate& slot = best[static_cast<std::size_t>(best_i)];
      if (best_d < slot.distance) slot = Candidate{best_i, id, p_w, best_d};
    }
  }
  std::vector<loop::Correspondence3d> correspondences;
  std::vector<std::pair<int, map::MapPointId>> matched;
  for (const Candidate& c : best) {
    if (c.keypoint < 0) continue;
    loop::Correspondence3d correspondence;
    correspondence.p_a = frame.p_c(c.keypoint);
    correspondence.p_b = c.p_w;
    correspondence.sigma_m = std::sqrt(2.0) * loop::depthSigma_m(frame.depth_m(c.keypoint));
    correspondences.push_back(correspondence);
    matched.emplace_back(c.keypoint, c.point);
  }
  log::debug("re-acquisition at t = ", frame.t_s(), " s: sigma ", sigma_p, " m / ", sigma_r, " rad, ",
             nearby.size(), " keyframes, ", projected, " of ", considered, " points projected (", with_candidate, " with a static keypoint in the window, ",
             below_distance, " within the distance), ", correspondences.size(), " matches of ",
             staticKeypointsWithDepth(frame), " static keypoints with depth");
  const int min_ransac = options_.relocalisation.min_ransac_inliers;
  if (static_cast<int>(correspondences.size()) < min_ransac) return 0;
  loop::Se3RansacOptions ransac_options;
  ransac_options.min_inliers = min_ransac;
  ransac_options.max_iterations = kReacquireRansacIterations;
  ransac_options.seed = static_cast<std::uint32_t>(std::llround(frame.t_s() * 1000.0)) * 7919u + 29u;
  const loop::Se3RansacResult ransac = loop::estimateSe3Ransac(correspondences, ransac_options);
  if (!ransac.success) {
    log::debug("re-acquisition: ", ransac.num_inliers, " RANSAC inliers of ", correspondences.size());
    return 0;
  }

  // The gate: the vision pose must agree with the IMU prediction.
  const double position_gate_m = o.reacquire_gate_sigmas * sigma_p;
  const double rotation_gate_rad =
      std::max(o.reacquire_gate_sigmas * sigma_r, o.reacquire_min_rotation_gate_deg * M_PI / 180.0);
  const auto withinGate = [&](const SE3& T_w_c, const char* stage) {
    const double dp_m = (T_w_c.translation() - centre_w).norm();
    const double dr_rad = rotationAngle_rad(T_w_c, T_w_c_pred);
    const bool ok = dp_m <= position_gate_m && dr_rad <= rotation_gate_rad;
    log::debug("re-acquisition ", stage, ": ", dp_m, " m (gate ", position_gate_m, "), ", dr_rad * 180.0 / M_PI,
               " deg (gate ", rotation_gate_rad * 180.0 / M_PI, ") from the prediction", ok ? "" : ": rejected");
    return ok;
  };
  const SE3 T_w_c_ransac = ransac.T_a_b.inverse();  // T_a_b = T_c_w
  if (!withinGate(T_w_c_ransac, "RANSAC")) return 0;

  // Refinement as a relocalisation: vision alone (the prediction's uncertainty no longer widens
  // the windows), then the local map of the matched points.
  const map::KeyFrameId reference_before = reference_kf_;
  const std::shared_ptr<map::KeyFrame> reference_ptr_before = reference_kf_ptr_;
  const double saved_sigma_p = stats_.predicted_position_sigma_m;
  const double saved_sigma_r = stats_.predicted_rotation_sigma_rad;
  stats_.predicted_position_sigma_m = 0.0;
  stats_.predicted_rotation_sigma_rad = 0.0;
  clearMatches(frame);
  for (std::size_t k = 0; k < matched.size(); ++k) {
    if (ransac.inliers[k]) frame.map_points[static_cast<std::size_t>(matched[k].first)] = matched[k].second;
  }
  frame.setPose_T_w_c(T_w_c_ransac);
  int inliers = optimisePose(frame, frame.T_w_b(), true);
  if (inliers >= min_ransac) {
    updateLocalMap(frame);
    searchLocalMap(frame);
    inliers = optimisePose(frame, frame.T_w_b(), false);
  }
  stats_.predicted_position_sigma_m = saved_sigma_p;
  stats_.predicted_rotation_sigma_rad = saved_sigma_r;
  if (inliers >= o.reacquire_min_inliers && withinGate(frame.T_w_c(), "refined")) {
    log::info("re-acquired map ", active.id(), " at t = ", frame.t_s(), " s after ", frame.t_s() - last_tracked_t_s_,
              " s lost: ", ransac.num_inliers, " RANSAC inliers of ", correspondences.size(), ", ", inliers,
              " after the local map, ", (frame.T_w_c().translation() - centre_w).norm(),
              " m from the IMU prediction (sigma ", sigma_p, " m)");
    return std::max(inliers, optimiseStateAfterGap(frame));
  }
  log::debug("re-acquisition: ", inliers, " inliers after the local map (", o.reacquire_min_inliers, " needed)");
  reference_kf_ = reference_before;
  reference_kf_ptr_ = reference_ptr_before;
  clearMatches(frame);
  return 0;
}

}  // namespace ltlo::tracking
