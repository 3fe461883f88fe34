#pragma once
/// Rigid alignment of 3-D-3-D correspondences (namespace ltlo::place): closed-form SE3 (Umeyama
/// without scale, depth fixes it) and a deterministic RANSAC on minimal sets of three.
#include <cstdint>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"

namespace ltlo::place {

/// One correspondence p_a ~ T_a_b * p_b (m), with the standard deviation of the distance after
/// alignment (m per axis, e.g. from both points' depth noise, see depthSigma_m).
struct Correspondence3d {
  Vec3 p_a = Vec3::Zero();
  Vec3 p_b = Vec3::Zero();
  double sigma_m = 0.01;
};

/// RGB-D depth noise grows with depth squared: sigma = max(min_sigma_m, coefficient * depth^2).
double depthSigma_m(double depth_m, double coefficient_per_m = 0.003, double min_sigma_m = 0.002);

/// T_a_b minimising sum w_i |p_a - T_a_b p_b|^2 (weights 1 when `weights` is empty). Needs >= 3
/// non-collinear points; asserts on mismatched sizes.
SE3 alignRigid(const std::vector<Vec3>& p_a, const std::vector<Vec3>& p_b, const std::vector<double>& weights = {});

struct Se3RansacOptions {
  int max_iterations = 300;
  /// inlier when |p_a - T p_b|^2 / sigma^2 < chi2_3d (95% of chi2 with 3 dof)
  double chi2_3d = 7.815;
  /// accept only with at least this many inliers (Loop.MinInliers)
  int min_inliers = 20;
  /// stop early once this fraction of correspondences are inliers
  double early_stop_ratio = 0.9;
  std::uint32_t seed = 1;
};

struct Se3RansacResult {
  bool success = false;
  SE3 T_a_b;                  ///< refined on the inliers (identity when not successful)
  std::vector<bool> inliers;  ///< per correspondence
  int num_inliers = 0;
  int iterations = 0;
};

/// RANSAC over minimal sets of three (seeded, deterministic), then two rounds of weighted
/// refinement (1 / sigma^2) on the inliers with inlier re-selection. success = num_inliers >= min_inliers.
Se3RansacResult estimateSe3Ransac(const std::vector<Correspondence3d>& correspondences,
                                  const Se3RansacOptions& options = Se3RansacOptions());

}  // namespace ltlo::place
