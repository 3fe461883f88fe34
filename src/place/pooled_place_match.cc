#include "ltlo/place/pooled_place_match.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "ltlo/map/keyframe.h"
#include "ltlo/optim/reprojection_edges.h"
#include "ltlo/place/se3_ransac.h"

namespace ltlo::place {

namespace {

/// Noise every pooled match gets on top of its RGB-D noise (m, per axis): the window's relative
/// poses and the map point's own position error.
constexpr double kPoolingFloorSigma_m = 0.003;
/// Gauss-Newton iterations per round and rounds of inlier selection of the refinement.
constexpr int kRefineIterations = 8;
constexpr int kRefineRounds = 3;

/// One pooled match, in the first keyframe's camera frame.
struct PooledMatch {
  int view = 0;
  int keypoint = -1;
  map::MapPointId point;
  Vec3 p_c0 = Vec3::Zero();  ///< the keypoint's 3-D point in the first keyframe's camera (m)
  Vec3 p_w = Vec3::Zero();   ///< the target map point (m)
  Mat3 covariance_c0 = Mat3::Identity();  ///< of p_c0 - (target point), in the first camera's frame
  int distance = 257;
};

/// Covariance of a keypoint's 3-D point in its camera: lateral from the pixel noise at its scale,
/// along the axis from the depth noise (RGB-D: sigma_z ~ z^2).
Mat3 keypointCovariance_c(const map::KeyFrame& kf, int keypoint) {
  const double z = kf.depth_m(keypoint);
  const int octave = kf.keypoints()[static_cast<std::size_t>(keypoint)].octave;
  const double lateral_m = z * kf.scaleFactors()[static_cast<std::size_t>(octave)] / kf.camera().fx();
  const double depth_m = depthSigma_m(z);
  return Vec3(lateral_m * lateral_m, lateral_m * lateral_m, depth_m * depth_m).asDiagonal();
}

/// Information (world frame) of match m at the rotation R_w_c0: the keypoint's covariance twice
/// (the map point's own is of the same kind) plus the floor.
Mat3 informationOf(const PooledMatch& m, const Mat3& R_w_c0) {
  const Mat3 covariance_w = 2.0 * R_w_c0 * m.covariance_c0 * R_w_c0.transpose() +
                            kPoolingFloorSigma_m * kPoolingFloorSigma_m * Mat3::Identity();
  return covariance_w.inverse();
}

double chi2Of(const PooledMatch& m, const SE3& T_w_c0) {
  const Vec3 e = T_w_c0 * m.p_c0 - m.p_w;
  return e.dot(informationOf(m, T_w_c0.rotationMatrix()) * e);
}

/// Gauss-Newton on T_w_c0 (left perturbation [dphi; drho] in the world frame, or drho alone with
/// the rotation held) over the inliers, Huber-weighted but in the last round; inliers re-selected
/// between rounds by the 3-dof chi2 test. Returns the inlier count; writes the last information.
int refine(const std::vector<PooledMatch>& matches, bool hold_rotation, SE3& T_w_c0, std::vector<bool>& inlier,
           Mat6& information) {
  const double huber = std::sqrt(optim::kChi2Threshold3Dof);
  int count = 0;
  for (int round = 0; round < kRefineRounds; ++round) {
    const bool robust = round + 1 < kRefineRounds;
    for (int iteration = 0; iteration < kRefineIterations; ++iteration) {
      Mat6 H = Mat6::Zero();
      Vec6 b = Vec6::Zero();
      const Mat3 R_w_c0 = T_w_c0.rotationMatrix();
      for (std::size_t k = 0; k < matches.size(); ++k) {
        if (!inlier[k]) continue;
        const Vec3 q = T_w_c0 * matches[k].p_c0;
        const Vec3 e = q - matches[k].p_w;
        const Mat3 omega = informationOf(matches[k], R_w_c0);
        const double chi2 = e.dot(omega * e);
        const double w = robust && chi2 > huber * huber ? huber / std::sqrt(chi2) : 1.0;
        Eigen::Matrix<double, 3, 6> J;
        J.leftCols<3>() = -hat(q);
        J.rightCols<3>() = Mat3::Identity();
        H += w * J.transpose() * omega * J;
        b += w * J.transpose() * omega * e;
      }
      Vec6 delta = Vec6::Zero();
      if (hold_rotation) {
        const Eigen::LDLT<Mat3> ldlt(H.bottomRightCorner<3, 3>());
        if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return 0;
        delta.tail<3>() = -ldlt.solve(b.tail<3>());
      } else {
        const Eigen::LDLT<Mat6> ldlt(H);
        if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return 0;
        delta = -ldlt.solve(b);
      }
      const Mat3 R_delta = so3Exp(delta.head<3>());
      T_w_c0 = SE3(R_delta * T_w_c0.rotationMatrix(), R_delta * T_w_c0.translation() + delta.tail<3>());
      information = H;
      if (delta.norm() < 1e-9) break;
    }
    count = 0;
    for (std::size_t k = 0; k < matches.size(); ++k) {
      inlier[k] = chi2Of(matches[k], T_w_c0) < optim::kChi2Threshold3Dof;
      count += inlier[k] ? 1 : 0;
    }
    if (count < 3) return count;
  }
  // The information of the final inliers, unweighted.
  information.setZero();
  for (std::size_t k = 0; k < matches.size(); ++k) {
    if (!inlier[k]) continue;
    const Vec3 q = T_w_c0 * matches[k].p_c0;
    Eigen::Matrix<double, 3, 6> J;
    J.leftCols<3>() = -hat(q);
    J.rightCols<3>() = Mat3::Identity();
    information += J.transpose() * informationOf(matches[k], T_w_c0.rotationMatrix()) * J;
  }
  return count;
}

}  // namespace

std::vector<std::shared_ptr<map::KeyFrame>> poolingWindow(const std::shared_ptr<map::KeyFrame>& kf,
                                                          const map::Map& map, int max_keyframes) {
  std::vector<std::shared_ptr<map::KeyFrame>> window{kf};
  for (const map::KeyFrameId id : kf->bestCovisibles(static_cast<std::size_t>(std::max(0, max_keyframes - 1)))) {
    std::shared_ptr<map::KeyFrame> other = map.keyFrame(id);
    if (other && !other->isBad() && other->mapId() == kf->mapId()) window.push_back(std::move(other));
  }
  return window;
}

GuidedPlaceMatch pooledPlaceMatch(const std::vector<std::shared_ptr<map::KeyFrame>>& window,
                                  const map::Map& target, const SE3& T_w_c_pred,
                                  const GuidedPlaceMatchOptions& options, bool hold_rotation) {
  GuidedPlaceMatch result;
  if (window.empty() || !window.front()) return result;
  const SE3 T_c0_w_own = window.front()->T_w_c().inverse();

  // Each view's matches at its prediction; each target point kept for its best match.
  std::vector<PooledMatch> pooled;
  std::unordered_map<map::MapPointId, std::size_t> by_point;
  int views = 0;
  for (std::size_t v = 0; v < window.size(); ++v) {
    const map::KeyFrame& view = *window[v];
    if (view.isBad()) continue;
    ++views;
    const SE3 T_c0_cv = T_c0_w_own * view.T_w_c();
    int keyframes = 0, projected = 0;
    const std::vector<WindowMatch> found = windowMatches(view, target, T_w_c_pred * T_c0_cv, options, &keyframes, &projected);
    if (v == 0) result.keyframes = keyframes;
    result.projected += projected;
    const Mat3 R_c0_cv = T_c0_cv.rotationMatrix();
    for (const WindowMatch& match : found) {
      PooledMatch m;
      m.view = static_cast<int>(v);
      m.keypoint = match.keypoint;
      m.point = match.point;
      m.p_c0 = T_c0_cv * view.p_c(match.keypoint);
      m.p_w = match.p_w;
      m.covariance_c0 = R_c0_cv * keypointCovariance_c(view, match.keypoint) * R_c0_cv.transpose();
      m.distance = match.distance;
      const auto [it, inserted] = by_point.emplace(match.point, pooled.size());
      if (inserted) {
        pooled.push_back(m);
      } else if (m.distance < pooled[it->second].distance) {
        pooled[it->second] = m;
      }
    }
  }
  result.views = views;
  result.correspondences = static_cast<int>(pooled.size());
  if (result.correspondences < options.min_ransac_inliers) return result;

  std::vector<Correspondence3d> correspondences;
  correspondences.reserve(pooled.size());
  for (const PooledMatch& m : pooled) {
    Correspondence3d c;
    c.p_a = m.p_c0;
    c.p_b = m.p_w;
    c.sigma_m = std::sqrt(m.covariance_c0.trace() * 2.0 / 3.0 + kPoolingFloorSigma_m * kPoolingFloorSigma_m);
    correspondences.push_back(c);
  }
  const Se3RansacResult ransac = estimateSe3Ransac(correspondences, ransacOptionsOf(options));
  result.ransac_inliers = ransac.num_inliers;
  if (!ransac.success) return result;

  SE3 T_w_c0 = ransac.T_a_b.inverse();  // T_a_b = T_c0_w
  std::vector<bool> inlier = ransac.inliers;
  if (hold_rotation) {
    // The RANSAC inliers' mean translation under the held rotation starts the refinement.
    const Mat3 R_w_c0 = T_w_c_pred.rotationMatrix();
    Vec3 sum = Vec3::Zero();
    int n = 0;
    for (std::size_t k = 0; k < pooled.size(); ++k) {
      if (!inlier[k]) continue;
      sum += pooled[k].p_w - R_w_c0 * pooled[k].p_c0;
      ++n;
    }
    T_w_c0 = SE3(T_w_c_pred.quaternion(), sum / std::max(1, n));
  }
  Mat6 information = Mat6::Zero();
  result.refined_inliers = refine(pooled, hold_rotation, T_w_c0, inlier, information);
  if (result.refined_inliers < options.min_ransac_inliers) return result;
  result.T_w_c = T_w_c0;
  if (!withinPredictionGate(result.T_w_c, T_w_c_pred, options, &result.distance_m, &result.rotation_rad) &&
      options.apply_gate) {
    return result;
  }
  if (!hold_rotation) {
    const Eigen::LDLT<Mat6> ldlt(information);
    if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
      // [dphi; drho] perturbs on the left, in the world frame: dphi_z is the yaw about gravity.
      const double yaw_variance = ldlt.solve(Mat6::Identity())(2, 2);
      if (yaw_variance >= 0.0) result.yaw_sigma_rad = std::sqrt(yaw_variance);
    }
  }
  for (std::size_t k = 0; k < pooled.size(); ++k) {
    if (inlier[k] && pooled[k].view == 0) result.matches.emplace_back(pooled[k].keypoint, pooled[k].point);
  }
  result.nearest_keyframe = nearestSearchedKeyFrame(target, T_w_c_pred, options, result.T_w_c.translation());
  result.success = result.nearest_keyframe != nullptr;
  return result;
}

}  // namespace ltlo::place
