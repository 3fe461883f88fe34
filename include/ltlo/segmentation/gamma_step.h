#pragma once
/// The Gamma step of the dense initial segmentation (thesis Eq. 59, state fixed), in closed form.
///
/// With the state fixed, Eq. 59 restricted to Gamma = {gamma_0 .. gamma_{K-1}} is
///   E(Gamma) = sum_k gamma_k a_k + lambda_d [ sum_k (gamma_k - gamma~_k)^2
///                                             + sum_{(k1,k2) in V_i} (gamma_k1 - gamma_k2)^2 ]   (Eq. 54)
/// where a_k is cluster k's data coefficient (its Eq. 60 cost per pixel minus the price of calling
/// it dynamic, see DenseSolver) and gamma~ the prior. E is a convex quadratic; given the other
/// scores, gamma_k has the closed-form minimiser
///   gamma_k = clamp((gamma~_k + sum_{j in N(k)} gamma_j - a_k / (2 lambda_d)) / (1 + |N(k)|), 0, 1),
/// and sweeping it over k (exact coordinate descent) converges to the global minimum of the
/// box-constrained problem. With lambda_d = 0 each gamma_k is 1 for a_k < 0, 0 for a_k > 0 and
/// gamma~_k for a_k = 0.
#include <vector>

#include "ltlo/segmentation/cluster_map.h"

namespace ltlo::segmentation {

struct GammaProblem {
  std::vector<double> data;   ///< a_k, K entries
  std::vector<double> prior;  ///< gamma~_k in [0, 1], K entries
  std::vector<ClusterEdge> edges;  ///< V_i over [0, K)
  double lambda_d = 1.0;      ///< Dense.LambdaD (DenseSolverOptions::lambda_d), >= 0
};

/// E(Gamma) of the problem (gamma: K entries).
double gammaCost(const GammaProblem& problem, const std::vector<double>& gamma);

/// The minimiser of E over [0, 1]^K, starting from `start` (K entries; the prior when empty);
/// sweeps until no score moves by more than `tolerance` (at most max_sweeps).
std::vector<double> solveGamma(const GammaProblem& problem, const std::vector<double>& start = {},
                               int max_sweeps = 500, double tolerance = 1e-9);

}  // namespace ltlo::segmentation
