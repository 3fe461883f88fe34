// The closed-form Gamma step of Eq. 59 (gamma_step.h) against a brute-force minimiser of the same
// cost over a grid of [0, 1]^K, and its limiting cases.
#include "ltlo/segmentation/gamma_step.h"

#include <gtest/gtest.h>

#include <random>

namespace ltlo::segmentation {
namespace {

/// The minimum of gammaCost over the grid {0, 1/steps, ..., 1}^K (exhaustive).
double bruteForceMinimum(const GammaProblem& problem, int steps, std::vector<double>* best_gamma) {
  const std::size_t K = problem.data.size();
  std::vector<int> index(K, 0);
  std::vector<double> gamma(K, 0.0);
  double best = std::numeric_limits<double>::max();
  while (true) {
    for (std::size_t k = 0; k < K; ++k) gamma[k] = static_cast<double>(index[k]) / steps;
    const double cost = gammaCost(problem, gamma);
    if (cost < best) {
      best = cost;
      *best_gamma = gamma;
    }
    std::size_t k = 0;
    while (k < K && ++index[k] > steps) index[k++] = 0;
    if (k == K) break;
  }
  return best;
}

// Random problems with three clusters (data coefficients of both signs, priors in [0, 1], random
// V_i, lambda_d from 0.05 to 2): the closed form reaches the grid minimum (it is the exact
// minimiser, so it is never worse than a grid point) and lies within a grid step of the best grid
// point (the cost is strictly convex for lambda_d > 0).
TEST(GammaStep, ClosedFormMatchesBruteForceMinimiser) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> data(-1.5, 1.5), unit(0.0, 1.0), lambda(0.05, 2.0);
  constexpr int kSteps = 40;
  for (int trial = 0; trial < 20; ++trial) {
    GammaProblem problem;
    problem.lambda_d = lambda(rng);
    for (int k = 0; k < 3; ++k) {
      problem.data.push_back(data(rng));
      problem.prior.push_back(unit(rng));
    }
    for (int a = 0; a < 3; ++a) {
      for (int b = a + 1; b < 3; ++b) {
        if (unit(rng) < 0.5) problem.edges.push_back({a, b, 1});
      }
    }
    const std::vector<double> gamma = solveGamma(problem);
    std::vector<double> grid_gamma;
    const double grid_best = bruteForceMinimum(problem, kSteps, &grid_gamma);
    const double cost = gammaCost(problem, gamma);
    EXPECT_LE(cost, grid_best + 1e-9) << "trial " << trial;
    for (std::size_t k = 0; k < gamma.size(); ++k) {
      EXPECT_GE(gamma[k], 0.0);
      EXPECT_LE(gamma[k], 1.0);
      EXPECT_NEAR(gamma[k], grid_gamma[k], 1.5 / kSteps) << "trial " << trial << " cluster " << k;
    }
  }
}

// Without smoothness a cluster's score is the clamped prior minus a_k / (2 lambda_d).
TEST(GammaStep, WithoutNeighboursTheScoreIsTheShiftedPrior) {
  GammaProblem problem;
  problem.lambda_d = 0.5;
  problem.data = {-0.2, 0.3, 5.0, -5.0};
  problem.prior = {0.5, 0.5, 0.5, 0.5};
  const std::vector<double> gamma = solveGamma(problem);
  EXPECT_NEAR(gamma[0], 0.7, 1e-12);
  EXPECT_NEAR(gamma[1], 0.2, 1e-12);
  EXPECT_EQ(gamma[2], 0.0);
  EXPECT_EQ(gamma[3], 1.0);
}

// lambda_d = 0: the sign of the data decides; no data keeps the prior.
TEST(GammaStep, ZeroLambdaFollowsTheSignOfTheData) {
  GammaProblem problem;
  problem.lambda_d = 0.0;
  problem.data = {-0.1, 0.1, 0.0};
  problem.prior = {0.3, 0.3, 0.3};
  problem.edges = {{0, 1, 4}, {1, 2, 4}};
  EXPECT_EQ(solveGamma(problem), (std::vector<double>{1.0, 0.0, 0.3}));
}

// A chain of clusters with evidence only at one end: the smoothness over V_i carries it along
// (scores fall monotonically with the distance from the dynamic end).
TEST(GammaStep, SmoothnessSpreadsEvidenceAlongTheGraph) {
  GammaProblem problem;
  problem.lambda_d = 1.0;
  problem.data = {4.0, 0.0, 0.0, 0.0};
  problem.prior = {1.0, 1.0, 1.0, 1.0};
  problem.edges = {{0, 1, 1}, {1, 2, 1}, {2, 3, 1}};
  const std::vector<double> gamma = solveGamma(problem);
  EXPECT_LT(gamma[0], 0.5);
  for (int k = 0; k < 3; ++k) EXPECT_LT(gamma[k], gamma[k + 1]) << k;
  EXPECT_GT(gamma[3], 0.8);
}

}  // namespace
}  // namespace ltlo::segmentation
