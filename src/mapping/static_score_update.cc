#include "static_score_update.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "ltlo/core/assert.h"
#include "ltlo/optim/reprojection_edges.h"

namespace ltlo::mapping {

namespace {

double clamp01(double x) { return std::min(1.0, std::max(0.0, x)); }

/// phi(lambda_phi, x) = max(0, (x - lambda_phi) / (1 - lambda_phi)) of Eq. 57.
double phi(double lambda_phi, double x) { return std::max(0.0, (x - lambda_phi) / (1.0 - lambda_phi)); }

void checkSizes(const StaticScoreProblem& problem, const std::vector<double>* gamma, const std::vector<double>* beta) {
  LTLO_ASSERT(gamma == nullptr || gamma->size() == problem.clusters.size(),
              gamma->size() << " gammas for " << problem.clusters.size() << " clusters");
  LTLO_ASSERT(beta == nullptr || static_cast<int>(beta->size()) == problem.num_points,
              beta->size() << " betas for " << problem.num_points << " points");
}

}  // namespace

double windowMeanResidual(const std::vector<ScoreObservation>& observations, const std::vector<double>& weights) {
  LTLO_ASSERT(weights.size() == observations.size(), weights.size() << " weights for " << observations.size()
                                                                    << " observations");
  double sum = 0.0, total_weight = 0.0;
  for (std::size_t o = 0; o < observations.size(); ++o) {
    const double w2 = weights[o] * weights[o];
    sum += w2 * observations[o].r_sq;
    total_weight += w2;
  }
  return total_weight > 0.0 ? sum / total_weight : 0.0;
}

std::vector<double> betaPriors(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                               const std::vector<double>& gamma) {
  checkSizes(problem, &gamma, nullptr);
  // Eq. 57: beta~_j = phi(lambda_phi, sum_{(i,k) in K_j} gamma_ik / n(K_j)).
  std::vector<double> sum(static_cast<std::size_t>(problem.num_points), 0.0);
  std::vector<int> count(static_cast<std::size_t>(problem.num_points), 0);
  for (const ScoreObservation& o : problem.observations) {
    sum[static_cast<std::size_t>(o.point)] += gamma[static_cast<std::size_t>(o.cluster)];
    ++count[static_cast<std::size_t>(o.point)];
  }
  std::vector<double> prior(sum.size(), 1.0);
  for (std::size_t j = 0; j < prior.size(); ++j) {
    if (count[j] > 0) prior[j] = phi(options.lambda_phi, sum[j] / count[j]);
  }
  return prior;
}

GammaPriors gammaPriors(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                        const std::vector<double>& beta) {
  checkSizes(problem, nullptr, &beta);
  // Eq. 56 as a beta-weighted mean (header): gamma~_c = 1 - sum beta_j min(1, lambda_p d_j) / sum beta_j,
  // in [0, 1] since every term is.
  constexpr double kMinVotes = 1e-6;
  std::vector<double> sum(problem.clusters.size(), 0.0);
  std::vector<double> votes(problem.clusters.size(), 0.0);
  for (const DepthSample& s : problem.depth_samples) {
    const double b = s.point >= 0 ? beta[static_cast<std::size_t>(s.point)] : s.probe_beta;
    sum[static_cast<std::size_t>(s.cluster)] += b * std::min(1.0, options.lambda_p * s.disagreement_m);
    votes[static_cast<std::size_t>(s.cluster)] += b;
  }
  GammaPriors prior;
  prior.value.resize(problem.clusters.size());
  prior.weight.resize(problem.clusters.size());
  for (std::size_t c = 0; c < problem.clusters.size(); ++c) {
    prior.value[c] = votes[c] > kMinVotes ? 1.0 - sum[c] / votes[c] : problem.clusters[c].prior_without_samples;
    prior.weight[c] = std::max(1.0, votes[c]);
  }
  return prior;
}

std::vector<double> updateBeta(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                               const std::vector<double>& gamma, const std::vector<double>& beta_prior) {
  checkSizes(problem, &gamma, &beta_prior);
  // For one point, with A = sum_o gamma_c^2 a_o and C = sum_o (1 - gamma_c)^2 h over its
  // observations (Eq. 51, 53) and the prior of Eq. 55:
  //   E_j(beta) = beta^2 A + (1 - beta)^2 C + lambda_s (beta - beta~)^2,
  //   dE_j/dbeta = 2 beta A - 2 (1 - beta) C + 2 lambda_s (beta - beta~) = 0
  //   => beta = (C + lambda_s beta~) / (A + C + lambda_s).
  // A, C, lambda_s >= 0 and beta~ in [0, 1] put the numerator in [0, denominator]: beta in [0, 1].
  const double h = optim::huberLoss(problem.c_hat, options.huber_delta);
  std::vector<double> A(static_cast<std::size_t>(problem.num_points), 0.0);
  std::vector<double> C(A.size(), 0.0);
  for (const ScoreObservation& o : problem.observations) {
    const double g = gamma[static_cast<std::size_t>(o.cluster)];
    A[static_cast<std::size_t>(o.point)] += g * g * optim::huberLoss(o.r_sq, options.huber_delta);
    C[static_cast<std::size_t>(o.point)] += (1.0 - g) * (1.0 - g) * h;
  }
  std::vector<double> beta(A.size());
  for (std::size_t j = 0; j < beta.size(); ++j) {
    const double denominator = A[j] + C[j] + options.lambda_s;
    // A point no term constrains (lambda_s = 0, zero costs) keeps its prior.
    beta[j] = denominator > 0.0 ? clamp01((C[j] + options.lambda_s * beta_prior[j]) / denominator) : beta_prior[j];
  }
  return beta;
}

std::vector<double> updateGamma(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                                const std::vector<double>& beta, const GammaPriors& gamma_prior,
                                const std::vector<double>& gamma) {
  checkSizes(problem, &gamma, &beta);
  checkSizes(problem, &gamma_prior.value, nullptr);
  checkSizes(problem, &gamma_prior.weight, nullptr);
  // For the free clusters F of one keyframe, with P_c = sum_o beta_j^2 a_o and
  // Q_c = sum_o (1 - beta_j)^2 h over the observations of cluster c (Eq. 51, 53) and R_d (Eq. 54):
  //   E(gamma) = sum_c [gamma_c^2 P_c + (1 - gamma_c)^2 Q_c + lambda_d v_c (gamma_c - gamma~_c)^2]
  //            + lambda_d sum_{(a, b) in V} (gamma_a - gamma_b)^2.
  // dE/dgamma_c = 0 gives the linear system M gamma = b with
  //   M_cc = P_c + Q_c + lambda_d (v_c + deg_c),  M_cn = -lambda_d for each free neighbour n,
  //   b_c  = Q_c + lambda_d v_c gamma~_c + lambda_d sum over fixed neighbours n of gamma_n.
  // M is symmetric with a positive diagonal and non-positive off-diagonal entries, diagonally
  // dominant by P_c + Q_c + lambda_d v_c (+ lambda_d per fixed neighbour): a Stieltjes matrix when
  // that excess is positive, so positive definite with M^-1 >= 0 entrywise. Hence b >= 0 gives
  // gamma >= 0, and M 1 - b = P_c + lambda_d v_c (1 - gamma~_c) + lambda_d sum_fixed (1 - gamma_n)
  // >= 0 gives M (1 - gamma) >= 0, i.e. gamma <= 1: the box constraint of Eq. 50 is never active.
  const double h = optim::huberLoss(problem.c_hat, options.huber_delta);
  const std::size_t num_clusters = problem.clusters.size();
  std::vector<double> P(num_clusters, 0.0), Q(num_clusters, 0.0);
  for (const ScoreObservation& o : problem.observations) {
    const double b = beta[static_cast<std::size_t>(o.point)];
    P[static_cast<std::size_t>(o.cluster)] += b * b * optim::huberLoss(o.r_sq, options.huber_delta);
    Q[static_cast<std::size_t>(o.cluster)] += (1.0 - b) * (1.0 - b) * h;
  }
  // A free cluster with nothing constraining it (lambda_d = 0 and no observation) keeps its value.
  std::vector<bool> free(num_clusters, false);
  for (std::size_t c = 0; c < num_clusters; ++c) {
    free[c] = !problem.clusters[c].fixed && (options.lambda_d > 0.0 || P[c] + Q[c] > 0.0);
  }
  // Free clusters grouped by keyframe; each group is one system.
  std::unordered_map<int, std::vector<int>> groups;
  std::vector<int> local_index(num_clusters, -1);
  for (std::size_t c = 0; c < num_clusters; ++c) {
    if (!free[c]) continue;
    std::vector<int>& group = groups[problem.clusters[c].keyframe];
    local_index[c] = static_cast<int>(group.size());
    group.push_back(static_cast<int>(c));
  }
  std::unordered_map<int, std::vector<std::pair<int, int>>> group_edges;
  for (const auto& [a, b] : problem.neighbours) {
    LTLO_ASSERT(problem.clusters[static_cast<std::size_t>(a)].keyframe ==
                    problem.clusters[static_cast<std::size_t>(b)].keyframe,
                "neighbour clusters " << a << " and " << b << " belong to different keyframes");
    group_edges[problem.clusters[static_cast<std::size_t>(a)].keyframe].emplace_back(a, b);
  }

  std::vector<double> result = gamma;
  for (const auto& [keyframe, members] : groups) {
    const int n = static_cast<int>(members.size());
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd rhs(n);
    for (int l = 0; l < n; ++l) {
      const auto c = static_cast<std::size_t>(members[static_cast<std::size_t>(l)]);
      M(l, l) = P[c] + Q[c] + options.lambda_d * gamma_prior.weight[c];
      rhs[l] = Q[c] + options.lambda_d * gamma_prior.weight[c] * gamma_prior.value[c];
    }
    const auto edges = group_edges.find(keyframe);
    if (edges != group_edges.end()) {
      for (const auto& [a, b] : edges->second) {
        const int la = local_index[static_cast<std::size_t>(a)];
        const int lb = local_index[static_cast<std::size_t>(b)];
        if (la < 0 && lb < 0) continue;
        if (la >= 0) M(la, la) += options.lambda_d;
        if (lb >= 0) M(lb, lb) += options.lambda_d;
        if (la >= 0 && lb >= 0) {
          M(la, lb) -= options.lambda_d;
          M(lb, la) -= options.lambda_d;
        } else if (la >= 0) {
          rhs[la] += options.lambda_d * gamma[static_cast<std::size_t>(b)];
        } else {
          rhs[lb] += options.lambda_d * gamma[static_cast<std::size_t>(a)];
        }
      }
    }
    const Eigen::VectorXd solution = M.llt().solve(rhs);
    for (int l = 0; l < n; ++l) {
      if (std::isfinite(solution[l])) result[static_cast<std::size_t>(members[static_cast<std::size_t>(l)])] = clamp01(solution[l]);
    }
  }
  return result;
}

double staticScoreCost(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                       const StaticScores& scores, const std::vector<double>& beta_prior,
                       const GammaPriors& gamma_prior) {
  checkSizes(problem, &scores.gamma, &scores.beta);
  const double h = optim::huberLoss(problem.c_hat, options.huber_delta);
  double cost = 0.0;
  for (const ScoreObservation& o : problem.observations) {
    const double b = scores.beta[static_cast<std::size_t>(o.point)];
    const double g = scores.gamma[static_cast<std::size_t>(o.cluster)];
    cost += b * b * g * g * optim::huberLoss(o.r_sq, options.huber_delta) + (1.0 - b) * (1.0 - b) * (1.0 - g) * (1.0 - g) * h;
  }
  for (std::size_t c = 0; c < problem.clusters.size(); ++c) {
    if (problem.clusters[c].fixed) continue;
    const double d = scores.gamma[c] - gamma_prior.value[c];
    cost += options.lambda_d * gamma_prior.weight[c] * d * d;
  }
  for (const auto& [a, b] : problem.neighbours) {
    const double d = scores.gamma[static_cast<std::size_t>(a)] - scores.gamma[static_cast<std::size_t>(b)];
    cost += options.lambda_d * d * d;
  }
  for (int j = 0; j < problem.num_points; ++j) {
    const double d = scores.beta[static_cast<std::size_t>(j)] - beta_prior[static_cast<std::size_t>(j)];
    cost += options.lambda_s * d * d;
  }
  return cost;
}

namespace {
/// x <- x + kRelaxation (update - x): under-relaxed fixed-point iteration (see solveStaticScores).
constexpr double kRelaxation = 0.5;
void relax(const std::vector<double>& update, std::vector<double>* x) {
  for (std::size_t k = 0; k < x->size(); ++k) (*x)[k] += kRelaxation * (update[k] - (*x)[k]);
}
}  // namespace

std::vector<double> observationWeights(const StaticScoreProblem& problem, const StaticScores& scores) {
  checkSizes(problem, &scores.gamma, &scores.beta);
  std::vector<double> weights;
  weights.reserve(problem.observations.size());
  for (const ScoreObservation& o : problem.observations) {
    weights.push_back(scores.beta[static_cast<std::size_t>(o.point)] * scores.gamma[static_cast<std::size_t>(o.cluster)]);
  }
  return weights;
}

StaticScores solveStaticScores(const StaticScoreProblem& problem, const StaticScoreOptions& options,
                               StaticScores initial, double* c_hat) {
  checkSizes(problem, &initial.gamma, &initial.beta);
  StaticScores scores = std::move(initial);
  StaticScoreProblem current = problem;  // c^ follows the weights
  for (int sweep = 0; sweep < options.sweeps; ++sweep) {
    current.c_hat = windowMeanResidual(current.observations, observationWeights(current, scores));
    const std::vector<double> beta_prior = betaPriors(current, options, scores.gamma);
    relax(updateBeta(current, options, scores.gamma, beta_prior), &scores.beta);
    const GammaPriors gamma_prior = gammaPriors(current, options, scores.beta);
    relax(updateGamma(current, options, scores.beta, gamma_prior, scores.gamma), &scores.gamma);
  }
  if (c_hat != nullptr) *c_hat = current.c_hat;
  return scores;
}

}  // namespace ltlo::mapping
