#include "seam_fusion.h"

#include <algorithm>
#include <unordered_set>

#include "ltlo/features/matching.h"
#include "ltlo/map/map_point.h"
#include "ltlo/optim/reprojection_edges.h"

namespace ltlo::loop {

namespace {

/// Chi-square 95% gates of the RGB-D [u, v, u_r] and monocular [u, v] observation (px^2 / sigma^2).
constexpr double kGate3Dof = optim::kChi2Threshold3Dof;
constexpr double kGate2Dof = optim::kChi2Threshold2Dof;
constexpr double kMinDepth_m = 0.05;
/// The point's distance range and viewing cone (map_point.h's visibility test).
using map::kMaxDistanceFactor;
using map::kMinDistanceFactor;
using map::kMinViewingCos;

/// The best static keypoint of `target` for a point at p_w, or -1.
int bestKeypoint(const map::KeyFrame& target, const SE3& T_c_w, const Vec3& centre_w, const map::MapPoint& point,
                 const Vec3& p_w, const std::vector<bool>& is_static, const SeamFusionOptions& options) {
  const Vec3 p_c = T_c_w * p_w;
  if (p_c.z() < kMinDepth_m) return -1;
  const PinholeCamera& camera = target.camera();
  const Vec2 uv = camera.project(p_c);
  if (!camera.isInImage(uv)) return -1;
  const Vec3 ray_w = p_w - centre_w;
  const double distance_m = ray_w.norm();
  if (point.maxDistance_m() > 0.0 && (distance_m < kMinDistanceFactor * point.minDistance_m() ||
                                      distance_m > kMaxDistanceFactor * point.maxDistance_m())) {
    return -1;
  }
  if (point.normal_w().squaredNorm() > 0.0 && ray_w.dot(point.normal_w()) < kMinViewingCos * distance_m) return -1;
  const std::vector<float>& scales = target.scaleFactors();
  const int level = scales.empty() ? 0 : point.predictScale(distance_m, scales);
  const double scale = scales.empty() ? 1.0 : scales[static_cast<std::size_t>(level)];
  const std::vector<int> area = target.featuresInArea(static_cast<float>(uv.x()), static_cast<float>(uv.y()),
                                                      static_cast<float>(options.radius_px * scale),
                                                      std::max(0, level - 1), level + 1);
  const double u_r_predicted = uv.x() - options.bf_px_m / p_c.z();
  const features::Descriptor descriptor = point.descriptor();
  int best = -1;
  int best_distance = options.max_hamming + 1;
  for (const int i : area) {
    const auto k = static_cast<std::size_t>(i);
    if (!is_static[k]) continue;
    const features::Keypoint& kp = target.keypoints()[k];
    const double sigma = scales.empty() ? 1.0 : scales[std::min<std::size_t>(static_cast<std::size_t>(kp.octave), scales.size() - 1)];
    const double e_u = uv.x() - kp.x_px;
    const double e_v = uv.y() - kp.y_px;
    const float depth_m = target.depth_m(i);
    double chi2 = e_u * e_u + e_v * e_v;
    if (depth_m > 0.0f) {
      const double e_r = u_r_predicted - (kp.x_px - options.bf_px_m / depth_m);
      chi2 += e_r * e_r;
    }
    if (chi2 / (sigma * sigma) > (depth_m > 0.0f ? kGate3Dof : kGate2Dof)) continue;
    const int distance = features::hammingDistance(descriptor, target.descriptors()[k]);
    if (distance < best_distance) {
      best_distance = distance;
      best = i;
    }
  }
  return best;
}

}  // namespace

std::vector<std::shared_ptr<map::MapPoint>> pointsSeenBy(const map::Map& map,
                                                         const std::vector<std::shared_ptr<map::KeyFrame>>& keyframes,
                                                         double min_point_beta) {
  std::vector<std::shared_ptr<map::MapPoint>> points;
  std::unordered_set<map::MapPointId> seen;
  for (const std::shared_ptr<map::KeyFrame>& kf : keyframes) {
    if (!kf || kf->isBad()) continue;
    for (const map::MapPointId id : kf->mapPoints()) {
      if (!id.valid() || !seen.insert(id).second) continue;
      std::shared_ptr<map::MapPoint> point = map.mapPoint(id);
      if (point && !point->isBad() && point->beta() >= min_point_beta) points.push_back(std::move(point));
    }
  }
  return points;
}

SeamFusionStats fuseAcrossSeam(map::Map& map, const std::vector<std::shared_ptr<map::KeyFrame>>& targets,
                               const std::vector<std::shared_ptr<map::MapPoint>>& points,
                               const SeamFusionOptions& options) {
  SeamFusionStats stats;
  std::unordered_set<map::MapPointId> touched;
  for (const std::shared_ptr<map::KeyFrame>& target : targets) {
    if (!target || target->isBad()) continue;
    const SE3 T_w_c = target->T_w_c();
    const SE3 T_c_w = T_w_c.inverse();
    std::vector<bool> is_static(static_cast<std::size_t>(target->numKeypoints()), false);
    for (const int i : target->staticKeypoints()) is_static[static_cast<std::size_t>(i)] = true;
    for (const std::shared_ptr<map::MapPoint>& point : points) {
      if (point->isBad() || point->beta() < options.min_point_beta || point->indexIn(target->id())) continue;
      const int best = bestKeypoint(*target, T_c_w, T_w_c.translation(), *point, point->p_w(), is_static, options);
      if (best < 0) continue;
      const map::MapPointId existing_id = target->mapPoint(best);
      if (!existing_id.valid()) {
        if (map.addObservation(*target, best, *point)) {
          ++stats.linked;
          touched.insert(point->id());
        }
        continue;
      }
      const std::shared_ptr<map::MapPoint> existing = map.mapPoint(existing_id);
      if (!existing || existing->isBad() || existing_id == point->id()) continue;
      // The better observed point survives; the other one's observations move to it.
      const bool keep_existing = existing->numObservations() > point->numObservations();
      const map::MapPointId survivor = keep_existing ? existing_id : point->id();
      if (map.replaceMapPoint(keep_existing ? point->id() : existing_id, survivor)) {
        ++stats.replaced;
        touched.insert(survivor);
      }
    }
    map.updateConnections(*target);
  }
  for (const map::MapPointId id : touched) {
    if (const std::shared_ptr<map::MapPoint> point = map.mapPoint(id); point && !point->isBad()) {
      map.updateDescriptor(*point);
      map.updateNormalAndDistances(*point);
    }
  }
  return stats;
}

}  // namespace ltlo::loop
