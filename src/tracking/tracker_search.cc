// Tracker, part 2: the searches by projection (last frame, local map) and the motion-model step
// that chains them with the pose optimisation.
#include <algorithm>
#include <unordered_map>
#include <unordered_set>

#include "ltlo/features/matching.h"
#include "ltlo/map/map_point.h"
#include "ltlo/tracking/tracker.h"
#include "tracker_util.h"

namespace ltlo::tracking {

using detail::isMatched;

namespace {

/// Fewest matches before the pose is optimised by vision alone (below: the search window is
/// widened once). With the inertial optimisation, Tracking.MinInliersImu.
constexpr int kMinMatchesToOptimise = 20;

}  // namespace

int Tracker::trackWithMotionModel(map::Frame& frame, const SE3& T_w_b_pred) {
  const optim::InertialLink* link = inertialLink();
  const int min_matches = link != nullptr ? options_.tracking.min_inliers_imu : kMinMatchesToOptimise;
  // After a loss the prediction is older: search wider.
  const double radius_scale = state_ == TrackingState::kLost ? 2.0 : 1.0;
  int matches = matchLastFrame(frame, radius_scale);
  if (matches < kMinMatchesToOptimise) {
    std::fill(frame.map_points.begin(), frame.map_points.end(), map::MapPointId());
    matches = matchLastFrame(frame, 2.0 * radius_scale);
  }
  stats_.last_frame_matches = matches;
  if (matches >= min_matches) {
    stats_.last_frame_inliers = optimisePose(frame, T_w_b_pred, true, link);
  }
  // Local map from the frame's current matches (or the last frame's, if it matched nothing).
  updateLocalMap(stats_.last_frame_inliers >= min_matches ? frame : *last_frame_);
  stats_.local_map_matches = searchLocalMap(frame);
  int inliers = 0;
  if (stats_.local_map_matches >= min_matches) {
    inliers = optimisePose(frame, frame.T_w_b(), false, link);
  }
  if (options_.tracking.localisation_only) inliers = trackWithOdometry(frame, inliers);
  return inliers;
}

int Tracker::matchLastFrame(map::Frame& frame, double radius_scale) {
  map::Map& active = activeMap();
  const map::Frame& last = *last_frame_;
  const SE3 T_c_w = frame.T_w_c().inverse();
  const PinholeCamera& camera = frame.camera();
  features::RotationHistogram histogram;
  std::vector<std::pair<int, int>> candidates_matched;  // (current keypoint, last keypoint)
  std::vector<int> best_distance(static_cast<std::size_t>(frame.numKeypoints()), 257);
  active.mapPointsInto(last.map_points, &point_scratch_);
  std::vector<int>& area = area_scratch_;
  for (int j = 0; j < last.numKeypoints(); ++j) {
    if (!isMatched(last, j)) continue;
    const std::shared_ptr<map::MapPoint>& point = point_scratch_[static_cast<std::size_t>(j)];
    if (!point || point->isBad()) continue;
    const Vec3 p_c = T_c_w * point->p_w();
    if (p_c.z() <= 0.0) continue;
    const Vec2 uv = camera.project(p_c);
    if (!camera.isInImage(uv)) continue;
    const features::Keypoint& kp_last = last.keypoints()[static_cast<std::size_t>(j)];
    const int octave = kp_last.octave;
    const float radius = searchRadius(static_cast<float>(options_.last_frame_radius_px * radius_scale *
                                                         last.scaleFactors()[static_cast<std::size_t>(octave)]),
                                      p_c.z(), camera.fx());
    frame.featuresInArea(static_cast<float>(uv.x()), static_cast<float>(uv.y()), radius, std::max(0, octave - 1),
                         octave + 1, &area);
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

void Tracker::updateLocalMap(const map::Frame& frame) {
  map::Map& active = activeMap();
  // Keyframes observing the frame's matched points, weighted by how many they share.
  std::unordered_map<map::KeyFrameId, int> counter;
  map::Observations observations;  // reused across the points: no allocation per point
  for (int i = 0; i < frame.numKeypoints(); ++i) {
    if (!isMatched(frame, i)) continue;
    const auto point = active.mapPoint(frame.map_points[static_cast<std::size_t>(i)]);
    if (!point || point->isBad()) continue;
    point->observationsInto(&observations);
    for (const auto& [kf, index] : observations) ++counter[kf];
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
  active.mapPointsInto(local_points_, &point_scratch_);
  std::vector<int>& area = area_scratch_;
  for (std::size_t n = 0; n < local_points_.size(); ++n) {
    const map::MapPointId id = local_points_[n];
    if (already.count(id)) continue;
    const std::shared_ptr<map::MapPoint>& point = point_scratch_[n];
    if (!point || point->isBad()) continue;
    const Vec3 p_w = point->p_w();
    const Vec3 p_c = T_c_w * p_w;
    if (p_c.z() <= 0.0) continue;
    const Vec2 uv = camera.project(p_c);
    if (!camera.isInImage(uv)) continue;
    const Vec3 ray_w = p_w - centre_w;
    const double distance_m = ray_w.norm();
    if (point->maxDistance_m() > 0.0 &&
        (distance_m < map::kMinDistanceFactor * point->minDistance_m() ||
         distance_m > map::kMaxDistanceFactor * point->maxDistance_m())) {
      continue;
    }
    const Vec3 normal_w = point->normal_w();
    const double view_cos = normal_w.squaredNorm() > 0.0 ? ray_w.dot(normal_w) / distance_m : 1.0;
    if (view_cos < map::kMinViewingCos) continue;
    point->increaseVisible();
    const int level = point->predictScale(distance_m, frame.scaleFactors());
    const double window = view_cos > 0.998 ? 2.5 : 4.0;
    const float radius = searchRadius(static_cast<float>(options_.local_map_radius_px * window / 2.5 *
                                                         frame.scaleFactors()[static_cast<std::size_t>(level)]),
                                      distance_m, camera.fx());
    frame.featuresInArea(static_cast<float>(uv.x()), static_cast<float>(uv.y()), radius, std::max(0, level - 1), level,
                         &area);
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

float Tracker::searchRadius(float base_px, double depth_m, double fx_px) const {
  const double sigma_p = stats_.predicted_position_sigma_m;
  const double sigma_r = stats_.predicted_rotation_sigma_rad;
  if (sigma_p <= 0.0 && sigma_r <= 0.0) return base_px;
  // Reprojection standard deviation of a point at depth_m under the predicted pose covariance:
  // fx (sigma_p / z + sigma_r), sigma_p of the camera centre (lever arm included by the caller).
  const double sigma_px = fx_px * (sigma_p / std::max(depth_m, 0.1) + sigma_r);
  const double widened = std::min(options_.search_sigmas * sigma_px, options_.max_search_radius_px);
  return std::max(base_px, static_cast<float>(widened));
}

}  // namespace ltlo::tracking
