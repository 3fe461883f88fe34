#pragma once
/// The Gamma/B half of the robust visual-inertial BA (thesis Eq. 50-58), private to ltlo_mapping:
/// with the keyframe states and map points fixed, the static scores of the window's clusters
/// (gamma, one per cluster of each keyframe) and map points (beta) minimise
///
///   E(Gamma, B) = sum_o [ beta_j^2 gamma_c^2 a_o + (1 - beta_j)^2 (1 - gamma_c)^2 h ]     (Eq. 51, 53)
///               + lambda_d sum_c v_c (gamma_c - gamma~_c)^2
///               + lambda_d sum_{(c1, c2) in V} (gamma_c1 - gamma_c2)^2                    (Eq. 54)
///               + lambda_s sum_j (beta_j - beta~_j)^2                                     (Eq. 55)
///
/// over gamma, beta in [0, 1], where o = (j, c) runs over the observations (point j seen by a
/// keypoint of cluster c), a_o = rho_H(|r_o|^2) is the Huber cost of the whitened reprojection error
/// and h = rho_H(c^) the cost of the mean squared error c^ of the window. The IMU terms (Eq. 50, 58)
/// do not depend on Gamma and B. The priors are evaluated from the other block, as the thesis
/// alternates "by fixing one and analytically solving the other":
///   beta~_j  = phi(lambda_phi, mean of gamma_c over the clusters observing j)            (Eq. 57)
///   gamma~_c = 1 - sum_{j in M_c} beta_j min(1, lambda_p d_j) / sum_{j in M_c} beta_j     (Eq. 56)
/// over the map points M_c projecting into cluster c, d_j the depth disagreement of point j there
/// (depthDisagreement_m()). The thesis writes the mean of |beta_j d_j| over n(M_c): we normalise by
/// the sum of beta instead, so only static points vote (a dynamic point does not vote "agrees"),
/// and cap each term at 1 (one point cannot say more than "fully dynamic"). A cluster without such
/// points (or only dynamic ones) keeps its score from before the BA as its prior.
/// The prior's weight v_c = max(1, sum_{j in M_c} beta_j) is the number of static votes: the term
/// equals, up to a constant, sum_j beta_j (gamma_c - (1 - min(1, lambda_p d_j)))^2, one vote per
/// point as every observation counts once in Eq. 51. Eq. 54 weighs the prior once per cluster:
/// a cluster with five neighbours would then follow them whatever its own evidence says (a box
/// touching the floor and three of its own faces would stay static). With at most one vote v_c = 1
/// and the thesis' form is recovered.
///
/// Both halves have closed forms (derived in static_score_update.cc): beta_j is the minimiser of a
/// one-dimensional quadratic; the gammas of one keyframe solve a small symmetric positive-definite
/// linear system (diagonal + lambda_d times the Laplacian of V_i). Both minimisers lie in [0, 1]
/// without clamping (proofs in the .cc); they are clamped against round-off only.
#include <utility>
#include <vector>

namespace ltlo::mapping {

struct StaticScoreOptions {
  double lambda_d = 1.0;    ///< weight of R_d (gamma prior and smoothness), Eq. 54 (LocalMapping.LambdaD)
  double lambda_s = 1.0;    ///< weight of R_s (beta prior), Eq. 55 (Seg.LambdaS)
  double lambda_p = 2.0;    ///< 1/m, depth disagreement to gamma prior, Eq. 56 (Seg.LambdaP)
  double lambda_phi = 0.5;  ///< Eq. 57 (Seg.LambdaPhi)
  double huber_delta = 2.7955;  ///< rho_H threshold on the whitened |r| (sqrt of LocalMapping.HuberChi2)
  int sweeps = 5;           ///< B <-> Gamma sweeps per call (LocalMapping.ScoreSweeps)
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

/// A map point projecting into a cluster of a free keyframe, with its depth disagreement d >= 0 (m):
/// a point of the problem (its beta is estimated), or a probe point (point = -1: a map point
/// outside the window, seen by the fixed keyframes, with its beta as it is).
struct DepthSample {
  int cluster = 0;
  int point = 0;
  double disagreement_m = 0.0;
  double probe_beta = 1.0;  ///< beta of a probe point (point = -1)
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
/// gamma~ of every cluster and its weight v from the current betas (Eq. 56).
struct GammaPriors {
  std::vector<double> value;   ///< gamma~; prior_without_samples without static votes
  std::vector<double> weight;  ///< v_c >= 1
};
GammaPriors gammaPriors(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                        const std::vector<double>& beta);

/// B minimising E for fixed Gamma and beta~ (closed form per point).
std::vector<double> updateBeta(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                               const std::vector<double>& gamma, const std::vector<double>& beta_prior);
/// Gamma minimising E for fixed B and gamma~ (one linear system per keyframe); fixed clusters keep
/// their value from `gamma`.
std::vector<double> updateGamma(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                                const std::vector<double>& beta, const GammaPriors& gamma_prior,
                                const std::vector<double>& gamma);

/// E(Gamma, B) above with the given priors (for tests and diagnostics).
double staticScoreCost(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                       const StaticScores& scores, const std::vector<double>& beta_prior,
                       const GammaPriors& gamma_prior);

/// w_o = beta_j gamma_c of every observation: the static weight of its reprojection edge.
std::vector<double> observationWeights(const StaticScoreProblem& problem, const StaticScores& scores);

/// options.sweeps rounds of: c^ = windowMeanResidual() under the current weights; beta~ from
/// Gamma, B moved half-way to updateBeta; gamma~ from B, Gamma moved half-way to updateGamma
/// (problem.c_hat is not used). Each half-step is the exact minimiser for fixed priors, but the
/// priors follow the other block, and Eq. 53 lets either a point or its cluster take the blame for
/// a residual: undamped, a moving point in a cluster without depth evidence flips between
/// (beta low, gamma high) and (beta high, gamma low) from sweep to sweep. The half steps converge
/// to the fixed point in between in a few sweeps. `initial` holds the scores before (new points
/// beta = 1, clusters from tracking); `c_hat` (optional) receives the last c^.
StaticScores solveStaticScores(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                               StaticScores initial, double* c_hat = nullptr);

}  // namespace ltlo::mapping
