#include "ltlo/segmentation/gamma_step.h"

#include <algorithm>
#include <cmath>

#include "ltlo/core/assert.h"

namespace ltlo::segmentation {

namespace {

void checkProblem(const GammaProblem& problem) {
  const std::size_t K = problem.data.size();
  LTLO_ASSERT(problem.prior.size() == K, problem.prior.size() << " priors for " << K << " clusters");
  LTLO_ASSERT(problem.lambda_d >= 0.0, "lambda_d = " << problem.lambda_d);
  for (const ClusterEdge& edge : problem.edges) {
    LTLO_ASSERT(edge.a >= 0 && edge.a < edge.b && edge.b < static_cast<int>(K),
                "edge (" << edge.a << ", " << edge.b << ") out of range for " << K << " clusters");
  }
}

}  // namespace

double gammaCost(const GammaProblem& problem, const std::vector<double>& gamma) {
  checkProblem(problem);
  LTLO_ASSERT(gamma.size() == problem.data.size(), gamma.size() << " scores for " << problem.data.size() << " clusters");
  double data = 0.0, regulariser = 0.0;
  for (std::size_t k = 0; k < gamma.size(); ++k) {
    data += gamma[k] * problem.data[k];
    regulariser += (gamma[k] - problem.prior[k]) * (gamma[k] - problem.prior[k]);
  }
  for (const ClusterEdge& edge : problem.edges) {
    const double d = gamma[static_cast<std::size_t>(edge.a)] - gamma[static_cast<std::size_t>(edge.b)];
    regulariser += d * d;
  }
  return data + problem.lambda_d * regulariser;
}

std::vector<double> solveGamma(const GammaProblem& problem, const std::vector<double>& start, int max_sweeps,
                               double tolerance) {
  checkProblem(problem);
  const std::size_t K = problem.data.size();
  std::vector<double> gamma = start.empty() ? problem.prior : start;
  LTLO_ASSERT(gamma.size() == K, gamma.size() << " start scores for " << K << " clusters");
  if (problem.lambda_d <= 0.0) {
    for (std::size_t k = 0; k < K; ++k) {
      gamma[k] = problem.data[k] < 0.0 ? 1.0 : problem.data[k] > 0.0 ? 0.0 : problem.prior[k];
    }
    return gamma;
  }
  // Adjacency lists of V_i.
  std::vector<std::vector<int>> neighbours(K);
  for (const ClusterEdge& edge : problem.edges) {
    neighbours[static_cast<std::size_t>(edge.a)].push_back(edge.b);
    neighbours[static_cast<std::size_t>(edge.b)].push_back(edge.a);
  }
  for (double& g : gamma) g = std::clamp(g, 0.0, 1.0);
  const double inv_two_lambda = 0.5 / problem.lambda_d;
  for (int sweep = 0; sweep < max_sweeps; ++sweep) {
    double largest_move = 0.0;
    for (std::size_t k = 0; k < K; ++k) {
      double sum = problem.prior[k] - problem.data[k] * inv_two_lambda;
      for (const int j : neighbours[k]) sum += gamma[static_cast<std::size_t>(j)];
      const double next = std::clamp(sum / (1.0 + static_cast<double>(neighbours[k].size())), 0.0, 1.0);
      largest_move = std::max(largest_move, std::abs(next - gamma[k]));
      gamma[k] = next;
    }
    if (largest_move <= tolerance) break;
  }
  return gamma;
}

}  // namespace ltlo::segmentation
