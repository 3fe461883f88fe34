#include "ltlo/place/se3_ransac.h"

#include <Eigen/SVD>
#include <algorithm>
#include <random>

#include "ltlo/core/assert.h"

namespace ltlo::place {

double depthSigma_m(double depth_m, double coefficient_per_m, double min_sigma_m) {
  return std::max(min_sigma_m, coefficient_per_m * depth_m * depth_m);
}

SE3 alignRigid(const std::vector<Vec3>& p_a, const std::vector<Vec3>& p_b, const std::vector<double>& weights) {
  LTLO_ASSERT(p_a.size() == p_b.size(), "alignRigid: " << p_a.size() << " vs " << p_b.size() << " points");
  LTLO_ASSERT(weights.empty() || weights.size() == p_a.size(),
              "alignRigid: " << weights.size() << " weights for " << p_a.size() << " points");
  LTLO_ASSERT(p_a.size() >= 3, "alignRigid needs >= 3 points, got " << p_a.size());
  double weight_sum = 0.0;
  Vec3 centroid_a = Vec3::Zero();
  Vec3 centroid_b = Vec3::Zero();
  for (std::size_t i = 0; i < p_a.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    centroid_a += w * p_a[i];
    centroid_b += w * p_b[i];
    weight_sum += w;
  }
  LTLO_ASSERT(weight_sum > 0.0, "alignRigid: weights sum to " << weight_sum);
  centroid_a /= weight_sum;
  centroid_b /= weight_sum;
  Mat3 covariance = Mat3::Zero();  // sum w (a - ca)(b - cb)^T
  for (std::size_t i = 0; i < p_a.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    covariance += w * (p_a[i] - centroid_a) * (p_b[i] - centroid_b).transpose();
  }
  const Eigen::JacobiSVD<Mat3> svd(covariance, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 reflection = Mat3::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0) reflection(2, 2) = -1.0;
  const Mat3 R_a_b = svd.matrixU() * reflection * svd.matrixV().transpose();
  return SE3(R_a_b, centroid_a - R_a_b * centroid_b);
}

namespace {

/// Marks inliers of T_a_b; returns their count.
int classify(const std::vector<Correspondence3d>& correspondences, const SE3& T_a_b, double chi2,
             std::vector<bool>& inliers) {
  inliers.assign(correspondences.size(), false);
  int count = 0;
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    const Correspondence3d& c = correspondences[i];
    const double error2 = (c.p_a - T_a_b * c.p_b).squaredNorm() / (c.sigma_m * c.sigma_m);
    if (error2 < chi2) {
      inliers[i] = true;
      ++count;
    }
  }
  return count;
}

/// A minimal set spanning a triangle (not nearly collinear) on both sides.
bool wellConditioned(const Vec3& a0, const Vec3& a1, const Vec3& a2) {
  const Vec3 u = a1 - a0;
  const Vec3 v = a2 - a0;
  const double area2 = u.cross(v).norm();
  return area2 > 1e-3 * std::max(1e-12, u.norm() * v.norm());
}

}  // namespace

Se3RansacResult estimateSe3Ransac(const std::vector<Correspondence3d>& correspondences,
                                  const Se3RansacOptions& options) {
  Se3RansacResult result;
  result.inliers.assign(correspondences.size(), false);
  const int n = static_cast<int>(correspondences.size());
  if (n < 3 || n < options.min_inliers) return result;

  std::mt19937 rng(options.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<bool> inliers;
  SE3 best;
  int best_count = -1;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    ++result.iterations;
    const int i0 = pick(rng);
    int i1 = pick(rng);
    int i2 = pick(rng);
    if (i1 == i0 || i2 == i0 || i2 == i1) continue;
    const Correspondence3d& c0 = correspondences[static_cast<std::size_t>(i0)];
    const Correspondence3d& c1 = correspondences[static_cast<std::size_t>(i1)];
    const Correspondence3d& c2 = correspondences[static_cast<std::size_t>(i2)];
    if (!wellConditioned(c0.p_a, c1.p_a, c2.p_a) || !wellConditioned(c0.p_b, c1.p_b, c2.p_b)) continue;
    const SE3 T_a_b = alignRigid({c0.p_a, c1.p_a, c2.p_a}, {c0.p_b, c1.p_b, c2.p_b});
    const int count = classify(correspondences, T_a_b, options.chi2_3d, inliers);
    if (count > best_count) {
      best_count = count;
      best = T_a_b;
      if (count >= options.early_stop_ratio * n) break;
    }
  }
  if (best_count < 3) return result;

  // Refinement: weighted alignment on the inliers, re-selected after each round.
  int count = classify(correspondences, best, options.chi2_3d, inliers);
  for (int round = 0; round < 2 && count >= 3; ++round) {
    std::vector<Vec3> a, b;
    std::vector<double> w;
    for (std::size_t i = 0; i < correspondences.size(); ++i) {
      if (!inliers[i]) continue;
      a.push_back(correspondences[i].p_a);
      b.push_back(correspondences[i].p_b);
      w.push_back(1.0 / (correspondences[i].sigma_m * correspondences[i].sigma_m));
    }
    const SE3 refined = alignRigid(a, b, w);
    std::vector<bool> refined_inliers;
    const int refined_count = classify(correspondences, refined, options.chi2_3d, refined_inliers);
    if (refined_count < count) break;
    best = refined;
    inliers = refined_inliers;
    count = refined_count;
  }
  result.num_inliers = count;
  result.inliers = inliers;
  result.success = count >= options.min_inliers;
  result.T_a_b = result.success ? best : SE3();
  return result;
}

}  // namespace ltlo::place
