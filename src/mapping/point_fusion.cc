#include "point_fusion.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include "ltlo/features/matching.h"
#include "ltlo/map/map_point.h"
#include "ltlo/optim/reprojection_edges.h"

namespace ltlo::mapping {

namespace {

/// Points closer than this to the camera plane are not projected (m).
constexpr double kMinDepth_m = 0.05;
/// A point outside its distance range or viewing cone is not searched (map_point.h).
using map::kMaxDistanceFactor;
using map::kMinDistanceFactor;
using map::kMinViewingCos;

std::vector<std::shared_ptr<map::MapPoint>> livePointsOf(const map::Map& map, const map::KeyFrame& kf) {
  std::vector<std::shared_ptr<map::MapPoint>> points;
  map.mapPointsInto(kf.mapPoints(), &points);
  points.erase(std::remove_if(points.begin(), points.end(),
                              [](const std::shared_ptr<map::MapPoint>& point) { return !point || point->isBad(); }),
               points.end());
  return points;
}

}  // namespace

FusionStats fusePointsInto(map::Map& map, map::KeyFrame& target,
                           const std::vector<std::shared_ptr<map::MapPoint>>& points,
                           const FusionOptions& options, const std::vector<float>& level_sigma2) {
  FusionStats stats;
  if (target.isBad() || points.empty()) return stats;
  const SE3 T_w_c = target.T_w_c();
  const SE3 T_c_w = T_w_c.inverse();
  const Vec3 centre_w = T_w_c.translation();
  const PinholeCamera& camera = target.camera();
  const std::vector<float>& scales = target.scaleFactors();
  std::vector<bool> is_static(static_cast<std::size_t>(target.numKeypoints()), false);
  for (const int i : target.staticKeypoints()) is_static[static_cast<std::size_t>(i)] = true;
  std::vector<int> area;

  for (const std::shared_ptr<map::MapPoint>& point : points) {
    if (!point || point->isBad() || point->beta() < options.min_point_beta) continue;
    if (point->indexIn(target.id())) continue;
    const Vec3 p_w = point->p_w();
    const Vec3 p_c = T_c_w * p_w;
    if (p_c.z() < kMinDepth_m) continue;
    const Vec2 uv = camera.project(p_c);
    if (!camera.isInImage(uv)) continue;
    const Vec3 ray_w = p_w - centre_w;
    const double distance_m = ray_w.norm();
    if (distance_m < kMinDistanceFactor * point->minDistance_m() ||
        distance_m > kMaxDistanceFactor * point->maxDistance_m()) {
      continue;
    }
    if (ray_w.dot(point->normal_w()) < kMinViewingCos * distance_m) continue;
    const int level = point->predictScale(distance_m, scales);
    const float radius_px = static_cast<float>(options.radius_px * scales[static_cast<std::size_t>(level)]);
    target.featuresInArea(static_cast<float>(uv.x()), static_cast<float>(uv.y()), radius_px, std::max(0, level - 1),
                          level, &area);
    if (area.empty()) continue;
    // Predicted RGB-D observation [u, v, u_r] (reprojection_edges.h).
    const double u_r_pred = uv.x() - options.bf_px_m / p_c.z();
    const features::Descriptor descriptor = point->descriptor();
    int best = -1;
    int best_distance = 257;
    for (const int i : area) {
      const auto k = static_cast<std::size_t>(i);
      if (!is_static[k]) continue;  // static-only seam: no new links on dynamic clusters
      const features::Keypoint& kp = target.keypoints()[k];
      const double inv_sigma2 =
          1.0 / level_sigma2[std::min<std::size_t>(static_cast<std::size_t>(kp.octave), level_sigma2.size() - 1)];
      const double e_u = uv.x() - kp.x_px;
      const double e_v = uv.y() - kp.y_px;
      const float depth_m = target.depth_m(i);
      if (depth_m > 0.0f) {
        const double e_r = u_r_pred - (kp.x_px - options.bf_px_m / depth_m);
        if ((e_u * e_u + e_v * e_v + e_r * e_r) * inv_sigma2 > optim::kChi2Threshold3Dof) continue;
      } else if ((e_u * e_u + e_v * e_v) * inv_sigma2 > optim::kChi2Threshold2Dof) {
        continue;
      }
      const int distance = features::hammingDistance(descriptor, target.descriptors()[k]);
      if (distance < best_distance) {
        best_distance = distance;
        best = i;
      }
    }
    if (best < 0 || best_distance > options.max_hamming) continue;

    const map::MapPointId existing_id = target.mapPoint(best);
    if (existing_id.valid()) {
      if (existing_id == point->id()) continue;
      const std::shared_ptr<map::MapPoint> existing = map.mapPoint(existing_id);
      if (!existing || existing->isBad()) continue;
      // Keep the better established point (more observations); the other one is merged into it.
      const bool keep_existing = existing->numObservations() > point->numObservations();
      const bool merged = keep_existing ? map.replaceMapPoint(point->id(), existing_id)
                                        : map.replaceMapPoint(existing_id, point->id());
      if (merged) ++stats.replaced;
    } else if (map.addObservation(target, best, *point)) {
      ++stats.linked;
    }
  }
  return stats;
}

std::vector<std::shared_ptr<map::KeyFrame>> fusionNeighbours(const map::Map& map, const map::KeyFrame& kf,
                                                             const FusionOptions& options) {
  std::vector<std::shared_ptr<map::KeyFrame>> neighbours;
  std::unordered_set<map::KeyFrameId> seen{kf.id()};
  auto add = [&](map::KeyFrameId id) {
    if (neighbours.size() >= options.max_neighbours || !seen.insert(id).second) return;
    std::shared_ptr<map::KeyFrame> other = map.keyFrame(id);
    if (other && !other->isBad()) neighbours.push_back(std::move(other));
  };
  for (const map::KeyFrameId id : kf.bestCovisibles(options.first_neighbours)) add(id);
  const std::size_t first_level = neighbours.size();
  for (std::size_t k = 0; k < first_level; ++k) {
    for (const map::KeyFrameId id : neighbours[k]->bestCovisibles(options.second_neighbours)) add(id);
  }
  return neighbours;
}

FusionStats fuseWithNeighbours(map::Map& map, map::KeyFrame& kf, const FusionOptions& options,
                               const std::vector<float>& level_sigma2) {
  FusionStats stats;
  const std::vector<std::shared_ptr<map::KeyFrame>> neighbours = fusionNeighbours(map, kf, options);
  if (neighbours.empty()) return stats;

  const std::vector<std::shared_ptr<map::MapPoint>> own_points = livePointsOf(map, kf);
  for (const std::shared_ptr<map::KeyFrame>& target : neighbours) {
    stats += fusePointsInto(map, *target, own_points, options, level_sigma2);
  }

  std::vector<std::shared_ptr<map::MapPoint>> neighbour_points;
  std::unordered_set<map::MapPointId> seen;
  for (const std::shared_ptr<map::KeyFrame>& neighbour : neighbours) {
    for (std::shared_ptr<map::MapPoint>& point : livePointsOf(map, *neighbour)) {
      if (seen.insert(point->id()).second) neighbour_points.push_back(std::move(point));
    }
  }
  stats += fusePointsInto(map, kf, neighbour_points, options, level_sigma2);

  for (const std::shared_ptr<map::MapPoint>& point : livePointsOf(map, kf)) {
    map.updateDescriptor(*point);
    map.updateNormalAndDistances(*point);
  }
  map.updateConnections(kf);
  return stats;
}

}  // namespace ltlo::mapping
