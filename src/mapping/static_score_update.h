#pragma once
/// The Gamma/B half of the robust visual-inertial BA (thesis Eq. 50-58), private to ltlo_mapping:
/// with the keyframe states and map points fixed, the static scores of the window's clusters
/// (gamma, one per cluster of each keyframe) and map points (beta) minimise
///
///   E(Gamma, B) = sum_o [ beta_j^2 gamma_c^2 a_o + (1 - beta_j)^2 (1 - gamma_c)^2 h ]     (Eq. 51, 53)
///               + lambda_d sum_c (gamma_c - gamma~_c)^2
///               + lambda_d sum_{(c1, c2) in V} (gamma_c1 - gamma_c2)^2                    (Eq. 54)
///               + lambda_s sum_j (beta_j - beta~_j)^2                                     (Eq. 55)
///
/// over gamma, beta in [0, 1], where o = (j, c) runs over the observations (point j seen by a
/// keypoint of cluster c), a_o = rho_H(|r_o|^2) is the Huber cost of the whitened reprojection error
/// and h = rho_H(c^) the cost of the mean squared error c^ of the window. The IMU terms (Eq. 50, 58)
/// do not depend on Gamma and B. The priors are evaluated from the other block, as the thesis
/// alternates "by fixing one and analytically solving the other":
///   beta~_j  = phi(lambda_phi, mean of gamma_c over the clusters observing j)            (Eq. 57)
///   gamma~_c = 1 - mean over the map points M_c projecting into cluster c of
///              min(1, lambda_p beta_j d_j)                                              (Eq. 56)
/// with d_j the depth disagreement of point j there (depthDisagreement_m()); a cluster without such
/// points keeps its score from before the BA as its prior.
///
/// Both halves have closed forms (derived in static_score_update.cc): beta_j is the minimiser of a
/// one-dimensional quadratic; the gammas of one keyframe solve a small symmetric positive-definite
/// linear system (diagonal + lambda_d times the Laplacian of V_i). Both minimisers lie in [0, 1]
/// without clamping (proofs in the .cc); they are clamped against round-off only.
#include <utility>
#include <vector>

namespace ltlo::mapping {

struct StaticScoreOptions {
  double lambda_d = 1.0;    ///< weight of R_d (gamma prior and smoothness), Eq. 54 (Seg.LambdaD)
  double lambda_s = 1.0;    ///< weight of R_s (beta prior), Eq. 55 (Seg.LambdaS)
  double lambda_p = 2.0;    ///< 1/m, depth disagreement to gamma prior, Eq. 56 (Seg.LambdaP)
  double lambda_phi = 0.5;  ///< Eq. 57 (Seg.LambdaPhi)
  double huber_delta = 2.7955;  ///< rho_H threshold on the whitened |r| (sqrt of LocalMapping.HuberChi2)
  int sweeps = 3;           ///< B <-> Gamma alternations per call (LocalMapping.ScoreSweeps)
};

/// One observation o = (point, cluster) with its whitened squared reprojection error |r_o|^2.
struct ScoreObservation {
  int point = 0;
  int cluster = 0;
  double r_sq = 0.0;
};

/// A cluster of a window keyframe. Clusters of one keyframe share `keyframe` (their gammas are
/// solved together); fixed clusters (the no-depth cluster, clusters of keyframes held fixed)
/// keep their gamma.
struct ScoreCluster {
  int keyframe = 0;
  bool fixed = false;
  /// gamma~ when no map point projects into the cluster (its gamma before the BA).
  double prior_without_samples = 1.0;
};

/// A map point projecting into a cluster of a free keyframe, with its depth disagreement d >= 0 (m).
struct DepthSample {
  int cluster = 0;
  int point = 0;
  double disagreement_m = 0.0;
};

struct StaticScoreProblem {
  int num_points = 0;
  std::vector<ScoreCluster> clusters;
  std::vector<ScoreObservation> observations;
  /// V: pairs of connected clusters (of the same keyframe), Eq. 54.
  std::vector<std::pair<int, int>> neighbours;
  std::vector<DepthSample> depth_samples;
  /// c^ of Eq. 53: the mean squared reprojection error of the window (windowMeanResidual()); the
  /// update functions use it, solveStaticScores() re-estimates it every sweep.
  double c_hat = 0.0;
};

struct StaticScores {
  std::vector<double> gamma;  ///< per cluster
  std::vector<double> beta;   ///< per point
};

/// Depth disagreement of a map point with the keyframe's depth image where it projects (Eq. 56's
/// D_i(pi(T x_j)) - |T x_j|_z), one-sided: max(0, z_point - D) (m). A point behind the observed
/// surface says that surface occludes the static map there (a dynamic object in front); a point in
/// front of it (D > z) says the camera sees through where the point should be: evidence against
/// the point (its beta), not against the surface, so it does not lower that cluster's prior.
inline double depthDisagreement_m(double point_depth_m, double image_depth_m) {
  return point_depth_m > image_depth_m ? point_depth_m - image_depth_m : 0.0;
}

/// c^ of Eq. 53: the mean of r_sq over the observations, each weighted by weights[o]^2 (beta gamma
/// of the current estimate; all 1 gives the thesis' plain mean). Observations already judged
/// dynamic thus do not raise the price of judging more of them dynamic. 0 without weight.
double windowMeanResidual(const std::vector<ScoreObservation>& observations, const std::vector<double>& weights);

/// beta~ of every point from the current gammas (Eq. 57); 1 for a point without observations.
std::vector<double> betaPriors(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                               const std::vector<double>& gamma);
/// gamma~ of every cluster from the current betas (Eq. 56); prior_without_samples without samples.
std::vector<double> gammaPriors(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                                const std::vector<double>& beta);

/// B minimising E for fixed Gamma and beta~ (closed form per point).
std::vector<double> updateBeta(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                               const std::vector<double>& gamma, const std::vector<double>& beta_prior);
/// Gamma minimising E for fixed B and gamma~ (one linear system per keyframe); fixed clusters keep
/// their value from `gamma`.
std::vector<double> updateGamma(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                                const std::vector<double>& beta, const std::vector<double>& gamma_prior,
                                const std::vector<double>& gamma);

/// E(Gamma, B) above with the given priors (for tests and diagnostics).
double staticScoreCost(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                       const StaticScores& scores, const std::vector<double>& beta_prior,
                       const std::vector<double>& gamma_prior);

/// w_o = beta_j gamma_c of every observation: the static weight of its reprojection edge.
std::vector<double> observationWeights(const StaticScoreProblem& problem, const StaticScores& scores);

/// options.sweeps rounds of: c^ = windowMeanResidual() under the current weights; beta~ from
/// Gamma, B = updateBeta; gamma~ from B, Gamma = updateGamma (problem.c_hat is not used).
/// `initial` holds the scores before (new points beta = 1, clusters from tracking); `c_hat`
/// (optional) receives the last c^.
StaticScores solveStaticScores(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                               StaticScores initial, double* c_hat = nullptr);

}  // namespace ltlo::mapping
