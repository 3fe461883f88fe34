#include "ltlo/eval/trajectory_metrics.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

#include "ltlo/core/assert.h"
#include "ltlo/io/associate.h"

namespace ltlo::eval {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

}  // namespace

ErrorStats computeErrorStats(std::vector<double> errors) {
  ErrorStats stats;
  if (errors.empty()) return stats;
  stats.count = static_cast<int>(errors.size());
  double sum = 0.0;
  double sum_squares = 0.0;
  for (const double e : errors) {
    sum += e;
    sum_squares += e * e;
  }
  stats.mean = sum / stats.count;
  stats.rmse = std::sqrt(sum_squares / stats.count);
  std::sort(errors.begin(), errors.end());
  stats.min = errors.front();
  stats.max = errors.back();
  const size_t mid = errors.size() / 2;
  stats.median = errors.size() % 2 == 1 ? errors[mid] : 0.5 * (errors[mid - 1] + errors[mid]);
  return stats;
}

MatchedTrajectories associateTrajectories(const io::Trajectory& gt, const io::Trajectory& est,
                                          double max_dt_s) {
  std::vector<double> gt_times_s;
  std::vector<double> est_times_s;
  for (const io::StampedPose& pose : gt) gt_times_s.push_back(pose.t_s);
  for (const io::StampedPose& pose : est) est_times_s.push_back(pose.t_s);
  MatchedTrajectories matched;
  for (const auto& [i, j] : io::associateTimestamps(gt_times_s, est_times_s, max_dt_s)) {
    matched.gt.push_back(gt[i]);
    matched.est.push_back(est[j]);
  }
  return matched;
}

// Umeyama, "Least-squares estimation of transformation parameters between two point patterns",
// PAMI 1991, Eqs. 38-42 with x = estimate, y = ground truth.
Sim3 umeyamaAlignment(const std::vector<Vec3>& p_est, const std::vector<Vec3>& p_gt,
                      bool with_scale) {
  LTLO_ASSERT(p_est.size() == p_gt.size(),
              "point counts differ: " << p_est.size() << " vs " << p_gt.size());
  LTLO_ASSERT(!p_est.empty(), "no points to align");
  const double n = static_cast<double>(p_est.size());
  Vec3 mu_est = Vec3::Zero();
  Vec3 mu_gt = Vec3::Zero();
  for (size_t k = 0; k < p_est.size(); ++k) {
    mu_est += p_est[k];
    mu_gt += p_gt[k];
  }
  mu_est /= n;
  mu_gt /= n;
  double variance_est = 0.0;              // sigma_x^2, Eq. 36
  Mat3 covariance_gt_est = Mat3::Zero();  // Sigma_xy, Eq. 38
  for (size_t k = 0; k < p_est.size(); ++k) {
    const Vec3 d_est = p_est[k] - mu_est;
    const Vec3 d_gt = p_gt[k] - mu_gt;
    variance_est += d_est.squaredNorm();
    covariance_gt_est += d_gt * d_est.transpose();
  }
  variance_est /= n;
  covariance_gt_est /= n;

  const Eigen::JacobiSVD<Mat3> svd(covariance_gt_est, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 S = Mat3::Identity();  // Eq. 39/43: flip the smallest axis when a reflection would fit
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2, 2) = -1.0;
  const Mat3 R_gt_est = svd.matrixU() * S * svd.matrixV().transpose();
  double scale = 1.0;
  if (with_scale && variance_est > 0.0) {
    scale = (svd.singularValues().asDiagonal() * S).trace() / variance_est;  // Eq. 42
  }
  const Vec3 t_gt_est = mu_gt - scale * R_gt_est * mu_est;  // Eq. 41
  return Sim3(Quat(normalizeRotation(R_gt_est)), t_gt_est, scale);
}

AteResult computeAte(const MatchedTrajectories& matched, bool with_scale) {
  LTLO_ASSERT(matched.gt.size() == matched.est.size(), "matched trajectories differ in length");
  std::vector<Vec3> p_est;
  std::vector<Vec3> p_gt;
  for (size_t k = 0; k < matched.gt.size(); ++k) {
    p_est.push_back(matched.est[k].T_w_x.translation());
    p_gt.push_back(matched.gt[k].T_w_x.translation());
  }
  AteResult result;
  result.S_gt_est = umeyamaAlignment(p_est, p_gt, with_scale);
  std::vector<double> errors_m;
  for (size_t k = 0; k < p_est.size(); ++k) {
    errors_m.push_back((p_gt[k] - result.S_gt_est * p_est[k]).norm());
  }
  result.error_m = computeErrorStats(errors_m);
  return result;
}

AteResult computeAteFixed(const MatchedTrajectories& matched, const Sim3& S_gt_est) {
  LTLO_ASSERT(matched.gt.size() == matched.est.size(), "matched trajectories differ in length");
  AteResult result;
  result.S_gt_est = S_gt_est;
  std::vector<double> errors_m;
  for (size_t k = 0; k < matched.gt.size(); ++k) {
    errors_m.push_back((matched.gt[k].T_w_x.translation() - S_gt_est * matched.est[k].T_w_x.translation()).norm());
  }
  result.error_m = computeErrorStats(errors_m);
  return result;
}

RpeResult computeRpe(const MatchedTrajectories& matched, const Sim3& S_gt_est) {
  LTLO_ASSERT(matched.gt.size() == matched.est.size(), "matched trajectories differ in length");
  std::vector<double> trans_m;
  std::vector<double> trans_m_s;
  std::vector<double> rot_deg;
  std::vector<double> rot_deg_s;
  for (size_t i = 0; i + 1 < matched.gt.size(); ++i) {
    const SE3& Q_i = matched.gt[i].T_w_x;
    const SE3& Q_next = matched.gt[i + 1].T_w_x;
    const SE3 P_i = S_gt_est.transformPose(matched.est[i].T_w_x);
    const SE3 P_next = S_gt_est.transformPose(matched.est[i + 1].T_w_x);
    const SE3 E_i = (Q_i.inverse() * Q_next).inverse() * (P_i.inverse() * P_next);  // Eq. 12
    const double dt_s = matched.gt[i + 1].t_s - matched.gt[i].t_s;
    const double e_trans_m = E_i.translation().norm();
    const double e_rot_deg = so3Log(E_i.quaternion()).norm() * kRadToDeg;
    trans_m.push_back(e_trans_m);
    rot_deg.push_back(e_rot_deg);
    if (dt_s > 0.0) {
      trans_m_s.push_back(e_trans_m / dt_s);
      rot_deg_s.push_back(e_rot_deg / dt_s);
    }
  }
  RpeResult result;
  result.trans_m_frame = computeErrorStats(trans_m);
  result.trans_m_s = computeErrorStats(trans_m_s);
  result.rot_deg_frame = computeErrorStats(rot_deg);
  result.rot_deg_s = computeErrorStats(rot_deg_s);
  return result;
}

}  // namespace ltlo::eval
