#include "ltlo/place/guided_place_match.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdint>
#include <unordered_map>
#include <unordered_set>

#include "ltlo/features/matching.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/optim/pose_only_problem.h"
#include "ltlo/place/se3_ransac.h"

namespace ltlo::place {

namespace {

/// A keyframe looking the same way as the predicted camera (optical axes within 60 degrees) may
/// share points with it; the nearest of them form the search's map.
constexpr double kMinAxisCosine = 0.5;

/// Angle of the rotation between two camera poses (rad).
double rotationAngle_rad(const SE3& a, const SE3& b) {
  return so3Log(a.quaternion().conjugate() * b.quaternion()).norm();
}

/// The keyframes of `map` looking the same way as the predicted camera, nearest first, at most
/// options.max_keyframes, with their distances (m); the options' distance, age and exclusions apply.
std::vector<std::pair<double, std::shared_ptr<map::KeyFrame>>> keyFramesAround(
    const map::Map& map, const SE3& T_w_c_pred, const GuidedPlaceMatchOptions& options) {
  const Vec3 centre_w = T_w_c_pred.translation();
  const Vec3 axis_w = T_w_c_pred.quaternion() * Vec3::UnitZ();
  const std::vector<map::KeyFrameId>& excluded = options.excluded_keyframes;
  std::vector<std::pair<double, std::shared_ptr<map::KeyFrame>>> nearby;
  for (std::shared_ptr<map::KeyFrame>& kf : map.keyFrames()) {
    if (!kf || kf->isBad() || kf->t_s() >= options.max_keyframe_t_s) continue;
    if (std::find(excluded.begin(), excluded.end(), kf->id()) != excluded.end()) continue;
    const SE3 T_w_c = kf->T_w_c();
    if ((T_w_c.quaternion() * Vec3::UnitZ()).dot(axis_w) < kMinAxisCosine) continue;
    const double distance_m = (T_w_c.translation() - centre_w).norm();
    if (distance_m > options.max_keyframe_distance_m) continue;
    nearby.emplace_back(distance_m, std::move(kf));
  }
  const int max_keyframes = options.max_keyframes;
  std::sort(nearby.begin(), nearby.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second->id() < b.second->id();
  });
  if (static_cast<int>(nearby.size()) > max_keyframes) nearby.resize(static_cast<std::size_t>(max_keyframes));
  return nearby;
}

}  // namespace

std::shared_ptr<map::KeyFrame> nearestSearchedKeyFrame(const map::Map& map, const SE3& T_w_c_pred,
                                                       const GuidedPlaceMatchOptions& options, const Vec3& t_w_c) {
  std::shared_ptr<map::KeyFrame> nearest;
  double nearest_m = std::numeric_limits<double>::infinity();
  for (const auto& [distance_kf_m, kf] : keyFramesAround(map, T_w_c_pred, options)) {
    const double d = (kf->T_w_c().translation() - t_w_c).norm();
    if (d < nearest_m) {
      nearest_m = d;
      nearest = kf;
    }
  }
  return nearest;
}

namespace {

/// Static keypoints with depth of a view (one pass; the keyframe's flags take a lock).
template <class View>
std::vector<char> usableKeypoints(const View& view) {
  std::vector<char> usable(static_cast<std::size_t>(view.numKeypoints()), 0);
  for (const int i : view.staticKeypoints()) {
    if (view.depth_m(i) > 0.0f) usable[static_cast<std::size_t>(i)] = 1;
  }
  return usable;
}

}  // namespace

Se3RansacOptions ransacOptionsOf(const GuidedPlaceMatchOptions& options) {
  Se3RansacOptions ransac;
  ransac.min_inliers = options.min_ransac_inliers;
  ransac.max_iterations = options.ransac_iterations;
  ransac.seed = options.seed;
  return ransac;
}

bool withinPredictionGate(const SE3& T_w_c, const SE3& T_w_c_pred, const GuidedPlaceMatchOptions& options,
                          double* distance_m, double* rotation_rad) {
  const double dp_m = (T_w_c.translation() - T_w_c_pred.translation()).norm();
  const double dr_rad = rotationAngle_rad(T_w_c, T_w_c_pred);
  if (distance_m != nullptr) *distance_m = dp_m;
  if (rotation_rad != nullptr) *rotation_rad = dr_rad;
  const double position_gate_m = options.gate_sigmas * options.sigma_position_m;
  const double rotation_gate_rad =
      std::max(options.gate_sigmas * options.sigma_rotation_rad, options.min_rotation_gate_deg * M_PI / 180.0);
  return dp_m <= position_gate_m && dr_rad <= rotation_gate_rad;
}

template <class View>
std::vector<WindowMatch> windowMatches(const View& view, const map::Map& map, const SE3& T_w_c_pred,
                                       const GuidedPlaceMatchOptions& options, int* keyframes, int* projected) {
  const SE3 T_c_w_pred = T_w_c_pred.inverse();
  const Vec3 centre_w = T_w_c_pred.translation();

  const std::vector<char> usable = usableKeypoints(view);

  const std::vector<std::pair<double, std::shared_ptr<map::KeyFrame>>> nearby =
      keyFramesAround(map, T_w_c_pred, options);
  if (keyframes != nullptr) *keyframes = static_cast<int>(nearby.size());
  int num_projected = 0;

  // Projection of their points with the prediction; static keypoints with depth within the
  // window, best descriptor with the ratio test, each keypoint kept for its best point.
  const PinholeCamera& camera = view.camera();
  std::vector<WindowMatch> best(static_cast<std::size_t>(view.numKeypoints()));
  std::unordered_set<map::MapPointId> seen;
  for (const auto& [distance_kf_m, kf] : nearby) {
    for (const map::MapPointId id : kf->mapPoints()) {
      if (!id.valid() || !seen.insert(id).second) continue;
      const auto point = map.mapPoint(id);
      if (!point || point->isBad()) continue;
      const Vec3 p_w = point->p_w();
      const Vec3 p_c = T_c_w_pred * p_w;
      if (p_c.z() <= 0.1) continue;
      const Vec2 uv = camera.project(p_c);
      if (!camera.isInImage(uv)) continue;
      ++num_projected;
      const double distance_m = (p_w - centre_w).norm();
      const int level = point->predictScale(distance_m, view.scaleFactors());
      // Reprojection standard deviation under the predicted uncertainty.
      const double sigma_px = camera.fx() * (options.sigma_position_m / p_c.z() + options.sigma_rotation_rad);
      const double radius_px =
          std::clamp(options.gate_sigmas * sigma_px, options.min_radius_px, options.max_radius_px) *
          view.scaleFactors()[static_cast<std::size_t>(level)];
      const std::vector<int> area = view.featuresInArea(static_cast<float>(uv.x()), static_cast<float>(uv.y()),
                                                        static_cast<float>(radius_px), std::max(0, level - 1),
                                                        level + 1);
      const features::Descriptor descriptor = point->descriptor();
      int best_i = -1, best_d = 257, second_d = 257;
      for (const int i : area) {
        if (!usable[static_cast<std::size_t>(i)]) continue;
        const int d = features::hammingDistance(descriptor, view.descriptors()[static_cast<std::size_t>(i)]);
        if (d < best_d) {
          second_d = best_d;
          best_d = d;
          best_i = i;
        } else if (d < second_d) {
          second_d = d;
        }
      }
      if (best_i < 0 || best_d > options.max_descriptor_distance || best_d > options.ratio * second_d) continue;
      WindowMatch& slot = best[static_cast<std::size_t>(best_i)];
      if (best_d < slot.distance) slot = WindowMatch{best_i, id, p_w, best_d};
    }
  }
  if (projected != nullptr) *projected = num_projected;
  best.erase(std::remove_if(best.begin(), best.end(), [](const WindowMatch& m) { return m.keypoint < 0; }), best.end());
  return best;
}

template <class View>
GuidedPlaceMatch guidedPlaceMatch(const View& view, const map::Map& map, const SE3& T_w_c_pred,
                                  const GuidedPlaceMatchOptions& options) {
  GuidedPlaceMatch result;
  const PinholeCamera& camera = view.camera();
  const std::vector<WindowMatch> best =
      windowMatches(view, map, T_w_c_pred, options, &result.keyframes, &result.projected);
  std::vector<Correspondence3d> correspondences;
  std::vector<std::pair<int, map::MapPointId>> matched;
  std::unordered_map<int, Vec3> matched_p_w;  // keypoint -> its map point's position
  for (const WindowMatch& c : best) {
    Correspondence3d correspondence;
    correspondence.p_a = view.p_c(c.keypoint);
    correspondence.p_b = c.p_w;
    correspondence.sigma_m = std::sqrt(2.0) * depthSigma_m(view.depth_m(c.keypoint));
    correspondences.push_back(correspondence);
    matched.emplace_back(c.keypoint, c.point);
    matched_p_w.emplace(c.keypoint, c.p_w);
  }
  result.correspondences = static_cast<int>(correspondences.size());
  if (result.correspondences < options.min_ransac_inliers) return result;
  const Se3RansacResult ransac = estimateSe3Ransac(correspondences, ransacOptionsOf(options));
  result.ransac_inliers = ransac.num_inliers;
  if (!ransac.success) return result;
  result.T_w_c = ransac.T_a_b.inverse();  // T_a_b = T_c_w
  if (!withinPredictionGate(result.T_w_c, T_w_c_pred, options, &result.distance_m, &result.rotation_rad) &&
      options.apply_gate) {
    return result;
  }
  for (std::size_t k = 0; k < matched.size(); ++k) {
    if (ransac.inliers[k]) result.matches.push_back(matched[k]);
  }
  if (options.refine_pose) {
    optim::PoseOnlyProblem problem;
    problem.model.camera = camera;
    problem.model.T_c_x = view.T_b_c().inverse();
    problem.model.bf_px_m = options.bf_px_m;
    problem.T_w_b_init = result.T_w_c * view.T_b_c().inverse();
    for (const auto& [keypoint, point] : result.matches) {
      const features::Keypoint& kp = view.keypoints()[static_cast<std::size_t>(keypoint)];
      optim::PoseObservation observation;
      observation.p_w = matched_p_w.at(keypoint);
      observation.uv = Vec2(kp.x_px, kp.y_px);
      observation.depth_m = view.depth_m(keypoint);
      observation.sigma_px = view.scaleFactors()[static_cast<std::size_t>(kp.octave)];
      problem.observations.push_back(observation);
    }
    const optim::PoseOnlyResult refined = optim::optimizePose(problem);
    result.refined_inliers = refined.num_inliers;
    if (refined.num_inliers < options.min_ransac_inliers) return result;
    result.T_w_c = refined.T_w_b * view.T_b_c();
    const Eigen::LDLT<Mat6> ldlt(refined.pose_information);
    if (ldlt.info() == Eigen::Success && ldlt.isPositive() && refined.pose_information.diagonal().minCoeff() > 0.0) {
      // [dphi; drho] perturbs the body rotation on the right: the world-frame rotation covariance
      // is R_w_b Sigma R_w_b^T.
      const Mat3 covariance_b = ldlt.solve(Mat6::Identity()).topLeftCorner<3, 3>();
      const Mat3 R_w_b = refined.T_w_b.rotationMatrix();
      const double yaw_variance = (R_w_b * covariance_b * R_w_b.transpose())(2, 2);
      if (yaw_variance >= 0.0) result.yaw_sigma_rad = std::sqrt(yaw_variance);
    }
    std::vector<std::pair<int, map::MapPointId>> kept;
    for (std::size_t k = 0; k < result.matches.size(); ++k) {
      if (refined.inliers[k]) kept.push_back(result.matches[k]);
    }
    result.matches = std::move(kept);
    if (!withinPredictionGate(result.T_w_c, T_w_c_pred, options, &result.distance_m, &result.rotation_rad) &&
        options.apply_gate) {
      result.matches.clear();
      return result;
    }
  }
  result.nearest_keyframe = nearestSearchedKeyFrame(map, T_w_c_pred, options, result.T_w_c.translation());
  result.success = true;
  return result;
}

template <class View>
WorldOffsetVote voteWorldOffset(const View& view, const map::Map& map, const SE3& T_w_c_pred,
                                const GuidedPlaceMatchOptions& options, int max_descriptor_distance, double bin_m) {
  WorldOffsetVote vote;
  // The map's points around the prediction, once each.
  struct Point {
    Vec3 p_w;
    features::Descriptor descriptor;
  };
  std::vector<Point> points;
  std::unordered_set<map::MapPointId> seen;
  for (const auto& [distance_kf_m, kf] : keyFramesAround(map, T_w_c_pred, options)) {
    for (const map::MapPointId id : kf->mapPoints()) {
      if (!id.valid() || !seen.insert(id).second) continue;
      const auto point = map.mapPoint(id);
      if (!point || point->isBad()) continue;
      points.push_back(Point{point->p_w(), point->descriptor()});
    }
  }
  const std::vector<char> usable = usableKeypoints(view);
  const auto binOf = [bin_m](const Vec3& offset) {
    return Eigen::Vector3i(static_cast<int>(std::floor(offset.x() / bin_m)),
                           static_cast<int>(std::floor(offset.y() / bin_m)),
                           static_cast<int>(std::floor(offset.z() / bin_m)));
  };
  const auto keyOf = [](const Eigen::Vector3i& b) {
    return (static_cast<std::int64_t>(b.x() + (1 << 20)) << 42) | (static_cast<std::int64_t>(b.y() + (1 << 20)) << 21) |
           static_cast<std::int64_t>(b.z() + (1 << 20));
  };
  std::vector<Vec3> offsets;
  std::unordered_map<std::int64_t, int> bins;
  for (int i = 0; i < view.numKeypoints(); ++i) {
    if (!usable[static_cast<std::size_t>(i)]) continue;
    const Vec3 p_w = T_w_c_pred * view.p_c(i);
    const double radius_m = options.gate_sigmas * (options.sigma_position_m +
                                                   options.sigma_rotation_rad * static_cast<double>(view.depth_m(i)));
    const double radius2 = radius_m * radius_m;
    const features::Descriptor& descriptor = view.descriptors()[static_cast<std::size_t>(i)];
    for (const Point& point : points) {
      const Vec3 offset = point.p_w - p_w;
      if (offset.squaredNorm() > radius2) continue;
      if (features::hammingDistance(descriptor, point.descriptor) > max_descriptor_distance) continue;
      offsets.push_back(offset);
      ++bins[keyOf(binOf(offset))];
    }
  }
  vote.pairs = static_cast<int>(offsets.size());
  if (offsets.empty()) return vote;
  // The peak: the bin whose 27-neighbourhood holds the most votes.
  std::int64_t best_key = 0;
  Eigen::Vector3i best_bin = Eigen::Vector3i::Zero();
  int best_support = -1;
  for (const auto& [key, count] : bins) {
    (void)count;
    const int z = static_cast<int>(key & ((1 << 21) - 1)) - (1 << 20);
    const int y = static_cast<int>((key >> 21) & ((1 << 21) - 1)) - (1 << 20);
    const int x = static_cast<int>((key >> 42) & ((1 << 21) - 1)) - (1 << 20);
    int support = 0;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = bins.find(keyOf(Eigen::Vector3i(x + dx, y + dy, z + dz)));
          if (it != bins.end()) support += it->second;
        }
      }
    }
    if (support > best_support || (support == best_support && key < best_key)) {
      best_support = support;
      best_key = key;
      best_bin = Eigen::Vector3i(x, y, z);
    }
  }
  // The offset: mean of the votes around the peak.
  Vec3 sum = Vec3::Zero();
  int n = 0;
  for (const Vec3& offset : offsets) {
    if ((binOf(offset) - best_bin).cwiseAbs().maxCoeff() > 1) continue;
    sum += offset;
    ++n;
  }
  vote.support = n;
  vote.offset_w = sum / std::max(1, n);
  vote.found = n >= options.min_ransac_inliers;
  return vote;
}

template <class View>
GuidedPlaceMatch translationWithHeldRotation(const View& view, const map::Map& map, const GuidedPlaceMatch& found,
                                             const SE3& T_w_c_pred, int min_inliers, double min_inlier_m) {
  GuidedPlaceMatch result = found;
  result.success = false;
  result.matches.clear();
  const Mat3 R_w_c = T_w_c_pred.rotationMatrix();
  // Per match: t = p_w - R_w_c p_c, with the standard deviation of its depth on both sides.
  struct Pair {
    std::pair<int, map::MapPointId> match;
    Vec3 t_w;
    double sigma_m;
  };
  std::vector<Pair> pairs;
  for (const auto& match : found.matches) {
    const auto point = map.mapPoint(match.second);
    if (!point || point->isBad()) continue;
    const double depth_m = view.depth_m(match.first);
    if (!(depth_m > 0.0)) continue;
    pairs.push_back({match, point->p_w() - R_w_c * view.p_c(match.first), std::sqrt(2.0) * depthSigma_m(depth_m)});
  }
  if (static_cast<int>(pairs.size()) < min_inliers) return result;
  Vec3 t_w;
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double> values;
    for (const Pair& p : pairs) values.push_back(p.t_w[axis]);
    std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2), values.end());
    t_w[axis] = values[values.size() / 2];
  }
  // Twice: the inliers around the current estimate, then their weighted mean.
  std::vector<bool> inlier(pairs.size(), false);
  for (int round = 0; round < 2; ++round) {
    Vec3 sum = Vec3::Zero();
    double weight = 0.0;
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      const double gate_m = std::max(min_inlier_m, 3.0 * pairs[k].sigma_m);
      inlier[k] = (pairs[k].t_w - t_w).norm() <= gate_m;
      if (!inlier[k]) continue;
      const double w = 1.0 / (pairs[k].sigma_m * pairs[k].sigma_m);
      sum += w * pairs[k].t_w;
      weight += w;
    }
    if (weight <= 0.0) return result;
    t_w = sum / weight;
  }
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    if (inlier[k]) result.matches.push_back(pairs[k].match);
  }
  if (static_cast<int>(result.matches.size()) < min_inliers) return result;
  result.T_w_c = SE3(T_w_c_pred.quaternion(), t_w);
  result.distance_m = (t_w - T_w_c_pred.translation()).norm();
  result.rotation_rad = 0.0;
  result.success = true;
  return result;
}

template GuidedPlaceMatch translationWithHeldRotation<map::KeyFrame>(const map::KeyFrame&, const map::Map&,
                                                                     const GuidedPlaceMatch&, const SE3&, int, double);
template GuidedPlaceMatch translationWithHeldRotation<map::Frame>(const map::Frame&, const map::Map&,
                                                                  const GuidedPlaceMatch&, const SE3&, int, double);
template WorldOffsetVote voteWorldOffset<map::KeyFrame>(const map::KeyFrame&, const map::Map&, const SE3&,
                                                       const GuidedPlaceMatchOptions&, int, double);
template WorldOffsetVote voteWorldOffset<map::Frame>(const map::Frame&, const map::Map&, const SE3&,
                                                    const GuidedPlaceMatchOptions&, int, double);
template std::vector<WindowMatch> windowMatches<map::Frame>(const map::Frame&, const map::Map&, const SE3&,
                                                            const GuidedPlaceMatchOptions&, int*, int*);
template std::vector<WindowMatch> windowMatches<map::KeyFrame>(const map::KeyFrame&, const map::Map&, const SE3&,
                                                               const GuidedPlaceMatchOptions&, int*, int*);
template GuidedPlaceMatch guidedPlaceMatch<map::Frame>(const map::Frame&, const map::Map&, const SE3&,
                                                      const GuidedPlaceMatchOptions&);
template GuidedPlaceMatch guidedPlaceMatch<map::KeyFrame>(const map::KeyFrame&, const map::Map&, const SE3&,
                                                         const GuidedPlaceMatchOptions&);

}  // namespace ltlo::place
