// The closed-form Gamma/B updates of the robust VIBA (thesis Eq. 50-58, static_score_update.h)
// against brute-force minimisers of the same cost for fixed states and points, the priors of
// Eq. 56-57 on hand-computed numbers, and the alternation separating a moving cluster.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include "../../src/mapping/static_score_update.h"

namespace ltlo::mapping {
namespace {

/// Minimum of a unimodal f on [lo, hi] by golden-section search to `tolerance`.
double goldenSection(const std::function<double(double)>& f, double lo, double hi, double tolerance) {
  const double ratio = (std::sqrt(5.0) - 1.0) / 2.0;
  double a = lo, b = hi;
  double c = b - ratio * (b - a), d = a + ratio * (b - a);
  while (b - a > tolerance) {
    if (f(c) < f(d)) {
      b = d;
    } else {
      a = c;
    }
    c = b - ratio * (b - a);
    d = a + ratio * (b - a);
  }
  return 0.5 * (a + b);
}

/// Brute force on one coordinate of a convex function on [0, 1]: a grid of 1e-3, then golden
/// section around the best grid value.
double bruteForce1d(const std::function<double(double)>& f) {
  double best_x = 0.0, best_f = f(0.0);
  for (int k = 1; k <= 1000; ++k) {
    const double x = k * 1e-3;
    const double value = f(x);
    if (value < best_f) {
      best_f = value;
      best_x = x;
    }
  }
  return goldenSection(f, std::max(0.0, best_x - 1e-3), std::min(1.0, best_x + 1e-3), 1e-10);
}

/// A random window: `num_keyframes` keyframes of `clusters_per_keyframe` clusters (the last of
/// each fixed, as the no-depth cluster), a chain of neighbours per keyframe, points observed by
/// 1-4 clusters with small (static-like) or large (dynamic-like) residuals, and depth samples.
StaticScoreProblem randomProblem(std::mt19937& rng, int num_keyframes, int clusters_per_keyframe, int num_points) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  StaticScoreProblem problem;
  problem.num_points = num_points;
  for (int i = 0; i < num_keyframes; ++i) {
    for (int k = 0; k < clusters_per_keyframe; ++k) {
      ScoreCluster cluster;
      cluster.keyframe = i;
      cluster.fixed = k + 1 == clusters_per_keyframe;
      cluster.prior_without_samples = unit(rng);
      problem.clusters.push_back(cluster);
      if (k + 2 < clusters_per_keyframe) {
        const int c = i * clusters_per_keyframe + k;
        problem.neighbours.emplace_back(c, c + 1);
      }
    }
    // One free cluster next to the fixed one: a fixed neighbour enters the right-hand side.
    problem.neighbours.emplace_back(i * clusters_per_keyframe, (i + 1) * clusters_per_keyframe - 1);
  }
  std::uniform_int_distribution<int> cluster_of(0, static_cast<int>(problem.clusters.size()) - 1);
  for (int j = 0; j < num_points; ++j) {
    const int views = 1 + static_cast<int>(unit(rng) * 4.0);
    for (int v = 0; v < views; ++v) {
      const bool large = unit(rng) < 0.3;
      problem.observations.push_back({j, cluster_of(rng), large ? 50.0 + 2000.0 * unit(rng) : 6.0 * unit(rng)});
    }
    if (unit(rng) < 0.5) problem.depth_samples.push_back({cluster_of(rng), j, unit(rng) < 0.5 ? 0.0 : unit(rng)});
  }
  std::vector<double> ones(problem.observations.size(), 1.0);
  problem.c_hat = windowMeanResidual(problem.observations, ones);
  return problem;
}

StaticScoreOptions testOptions() {
  StaticScoreOptions options;
  options.lambda_d = 10.0;
  options.lambda_s = 100.0;
  options.lambda_p = 2.0;
  options.lambda_phi = 0.5;
  options.huber_delta = std::sqrt(7.815);
  return options;
}

std::vector<double> randomScores(std::mt19937& rng, std::size_t n) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> scores(n);
  for (double& s : scores) s = unit(rng);
  return scores;
}

TEST(StaticScoreUpdate, BetaIsTheMinimiserOfTheCostForFixedGamma) {
  std::mt19937 rng(21);
  const StaticScoreProblem problem = randomProblem(rng, 3, 5, 40);
  const StaticScoreOptions options = testOptions();
  StaticScores scores{randomScores(rng, problem.clusters.size()), randomScores(rng, 40)};
  const std::vector<double> beta_prior = betaPriors(problem, options, scores.gamma);
  const GammaPriors gamma_prior = gammaPriors(problem, options, scores.beta);
  const std::vector<double> closed = updateBeta(problem, options, scores.gamma, beta_prior);
  for (int j = 0; j < problem.num_points; ++j) {
    StaticScores trial = scores;
    const auto cost_at = [&](double beta) {
      trial.beta[static_cast<std::size_t>(j)] = beta;
      return staticScoreCost(problem, options, trial, beta_prior, gamma_prior);
    };
    const double brute = bruteForce1d(cost_at);
    EXPECT_NEAR(closed[static_cast<std::size_t>(j)], brute, 1e-6) << "point " << j;
    EXPECT_LE(cost_at(closed[static_cast<std::size_t>(j)]), cost_at(brute) + 1e-9) << "point " << j;
  }
}

TEST(StaticScoreUpdate, GammaIsTheMinimiserOfTheCostForFixedBeta) {
  // One keyframe with three free clusters (and its fixed no-depth cluster): exhaustive grid over
  // the three gammas, then coordinate-wise golden section from the best grid point.
  std::mt19937 rng(22);
  const StaticScoreProblem problem = randomProblem(rng, 1, 4, 25);
  const StaticScoreOptions options = testOptions();
  StaticScores scores{randomScores(rng, problem.clusters.size()), randomScores(rng, 25)};
  const std::vector<double> beta_prior = betaPriors(problem, options, scores.gamma);
  const GammaPriors gamma_prior = gammaPriors(problem, options, scores.beta);
  const std::vector<double> closed = updateGamma(problem, options, scores.beta, gamma_prior, scores.gamma);
  EXPECT_EQ(closed[3], scores.gamma[3]);  // fixed cluster untouched

  StaticScores trial = scores;
  const auto cost = [&] { return staticScoreCost(problem, options, trial, beta_prior, gamma_prior); };
  double best = cost();
  std::vector<double> best_gamma = trial.gamma;
  for (int a = 0; a <= 50; ++a) {
    for (int b = 0; b <= 50; ++b) {
      for (int c = 0; c <= 50; ++c) {
        trial.gamma[0] = a / 50.0;
        trial.gamma[1] = b / 50.0;
        trial.gamma[2] = c / 50.0;
        const double value = cost();
        if (value < best) {
          best = value;
          best_gamma = trial.gamma;
        }
      }
    }
  }
  trial.gamma = best_gamma;
  for (int round = 0; round < 200; ++round) {
    for (int k = 0; k < 3; ++k) {
      trial.gamma[static_cast<std::size_t>(k)] = bruteForce1d([&](double g) {
        trial.gamma[static_cast<std::size_t>(k)] = g;
        return cost();
      });
    }
  }
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(closed[static_cast<std::size_t>(k)], trial.gamma[static_cast<std::size_t>(k)], 1e-5) << k;
  StaticScores closed_scores = scores;
  closed_scores.gamma = closed;
  EXPECT_LE(staticScoreCost(problem, options, closed_scores, beta_prior, gamma_prior), cost() + 1e-9);
}

TEST(StaticScoreUpdate, GammaOfSeveralKeyFramesIsOneMinimiser) {
  // Four keyframes solved at once: no coordinate change lowers the cost (the cost is a convex
  // quadratic in Gamma, so a coordinate-wise minimum is the minimum).
  std::mt19937 rng(23);
  const StaticScoreProblem problem = randomProblem(rng, 4, 6, 60);
  const StaticScoreOptions options = testOptions();
  StaticScores scores{randomScores(rng, problem.clusters.size()), randomScores(rng, 60)};
  const std::vector<double> beta_prior = betaPriors(problem, options, scores.gamma);
  const GammaPriors gamma_prior = gammaPriors(problem, options, scores.beta);
  scores.gamma = updateGamma(problem, options, scores.beta, gamma_prior, scores.gamma);
  const double at_closed = staticScoreCost(problem, options, scores, beta_prior, gamma_prior);
  for (std::size_t c = 0; c < problem.clusters.size(); ++c) {
    if (problem.clusters[c].fixed) continue;
    StaticScores trial = scores;
    const double brute = bruteForce1d([&](double g) {
      trial.gamma[c] = g;
      return staticScoreCost(problem, options, trial, beta_prior, gamma_prior);
    });
    EXPECT_NEAR(scores.gamma[c], brute, 1e-6) << "cluster " << c;
    trial.gamma[c] = brute;
    EXPECT_GE(staticScoreCost(problem, options, trial, beta_prior, gamma_prior), at_closed - 1e-9);
  }
}

TEST(StaticScoreUpdate, PriorsFollowEquations56And57) {
  StaticScoreProblem problem;
  problem.num_points = 3;
  problem.clusters = {{0, false, 0.7}, {0, false, 0.9}, {0, true, 1.0}};
  // Point 0 seen by clusters 0 and 1, point 1 by cluster 0, point 2 by nothing.
  problem.observations = {{0, 0, 1.0}, {0, 1, 1.0}, {1, 0, 1.0}};
  // Cluster 0: point 0 agrees (0 m), point 1 lies 0.3 m behind the surface; cluster 1: point 0 lies
  // 2 m behind (its term is capped at 1).
  problem.depth_samples = {{0, 0, 0.0}, {0, 1, 0.3}, {1, 0, 2.0}};
  StaticScoreOptions options;
  options.lambda_p = 2.0;
  options.lambda_phi = 0.5;
  const std::vector<double> beta_prior = betaPriors(problem, options, {0.9, 0.5, 1.0});
  EXPECT_NEAR(beta_prior[0], (0.7 - 0.5) / 0.5, 1e-12);  // phi(0.5, mean(0.9, 0.5))
  EXPECT_NEAR(beta_prior[1], (0.9 - 0.5) / 0.5, 1e-12);
  EXPECT_NEAR(beta_prior[2], 1.0, 1e-12);                // no observation: no vote
  EXPECT_NEAR(betaPriors(problem, options, {0.3, 0.5, 1.0})[1], 0.0, 1e-12);  // phi clips at 0
  const GammaPriors gamma_prior = gammaPriors(problem, options, {1.0, 0.5, 1.0});
  // beta-weighted: (1.0 * 0 + 0.5 * min(1, 2 * 0.3)) / (1.0 + 0.5).
  EXPECT_NEAR(gamma_prior.value[0], 1.0 - (0.5 * 0.6) / 1.5, 1e-12);
  EXPECT_NEAR(gamma_prior.weight[0], 1.5, 1e-12);  // the static votes
  EXPECT_NEAR(gamma_prior.value[1], 1.0 - 1.0, 1e-12);
  EXPECT_NEAR(gamma_prior.weight[1], 1.0, 1e-12);  // at least 1
  EXPECT_NEAR(gamma_prior.value[2], 1.0, 1e-12);   // no sample: its value before the BA
  // Only dynamic points project into cluster 1: no vote, its value before the BA.
  EXPECT_NEAR(gammaPriors(problem, options, {0.0, 0.5, 1.0}).value[1], 0.9, 1e-12);
  // A probe point (outside the window) votes with its own beta.
  problem.depth_samples.push_back({1, -1, 0.0, 1.0});
  EXPECT_NEAR(gammaPriors(problem, options, {1.0, 0.5, 1.0}).value[1], 1.0 - 1.0 / 2.0, 1e-12);
  EXPECT_DOUBLE_EQ(depthDisagreement_m(2.5, 1.0), 1.5);  // the surface occludes the point
  EXPECT_DOUBLE_EQ(depthDisagreement_m(1.0, 2.5), 0.0);  // seen through: not the cluster's fault
  // c^ weighted by w^2: an observation with weight 0 does not count.
  EXPECT_NEAR(windowMeanResidual({{0, 0, 2.0}, {0, 0, 4.0}, {0, 0, 1000.0}}, {1.0, 1.0, 0.0}), 3.0, 1e-12);
}

/// Two keyframes of three depth clusters each (and the fixed no-depth cluster): clusters 0 and 4
/// are one box, seen moving (its points reproject 10-20 sigma off in both keyframes); the others
/// are static background with chi2(3) residuals and depth samples agreeing within 1 cm. With
/// `occluding`, the box also hides 30 mapped background points (0.6 m behind its surface) in each
/// keyframe. Everything starts static (gamma = 1, new points beta = 1).
struct BoxWindow {
  StaticScoreProblem problem;
  std::vector<bool> is_box_point;
};

BoxWindow boxWindow(bool occluding) {
  std::mt19937 rng(24);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::chi_squared_distribution<double> chi2(3.0);
  BoxWindow window;
  StaticScoreProblem& problem = window.problem;
  for (int i = 0; i < 2; ++i) {
    for (int k = 0; k < 4; ++k) problem.clusters.push_back({i, k == 3, 1.0});
    problem.neighbours.emplace_back(4 * i, 4 * i + 1);  // the box touches the floor
    problem.neighbours.emplace_back(4 * i + 1, 4 * i + 2);
  }
  auto box = [](int c) { return c == 0 || c == 4; };
  int point = 0;
  for (int c : {0, 1, 2, 4, 5, 6}) {
    for (int n = 0; n < 15; ++n, ++point) {
      const int other = c < 4 ? c + 4 : c - 4;  // seen in both keyframes
      for (int view : {c, other}) {
        const double r_sq = box(c) ? std::pow(10.0 + 10.0 * unit(rng), 2) : chi2(rng);
        problem.observations.push_back({point, view, r_sq});
        if (!box(c)) problem.depth_samples.push_back({view, point, 0.01 * unit(rng)});
      }
      window.is_box_point.push_back(box(c));
    }
  }
  if (occluding) {
    for (int box_cluster : {0, 4}) {
      for (int n = 0; n < 30; ++n, ++point) {  // background behind the box, seen by the wall cluster of the other keyframe
        problem.observations.push_back({point, box_cluster == 0 ? 6 : 2, chi2(rng)});
        problem.depth_samples.push_back({box_cluster, point, 0.6});
        window.is_box_point.push_back(false);
      }
    }
  }
  problem.num_points = point;
  return window;
}

StaticScores solveFromAllStatic(const StaticScoreProblem& problem) {
  StaticScoreOptions options = testOptions();
  options.sweeps = 8;
  return solveStaticScores(problem, options,
                           {std::vector<double>(problem.clusters.size(), 1.0), std::vector<double>(problem.num_points, 1.0)});
}

void expectBoxPointsDynamicOthersStatic(const BoxWindow& window, const StaticScores& result) {
  for (int j = 0; j < window.problem.num_points; ++j) {
    if (window.is_box_point[static_cast<std::size_t>(j)]) {
      EXPECT_LT(result.beta[static_cast<std::size_t>(j)], 0.5) << "box point " << j;
    } else {
      EXPECT_GT(result.beta[static_cast<std::size_t>(j)], 0.5) << "static point " << j;
    }
  }
}

TEST(StaticScoreUpdate, OccludingBoxClustersAndPointsEndDynamic) {
  const BoxWindow window = boxWindow(true);
  const StaticScores result = solveFromAllStatic(window.problem);
  EXPECT_LT(result.gamma[0], 0.5);
  EXPECT_LT(result.gamma[4], 0.5);
  // Background clusters stay static (the floor, next to the box, is pulled down by R_d's smoothness).
  for (int c : {1, 2, 5, 6}) EXPECT_GT(result.gamma[static_cast<std::size_t>(c)], 0.6) << "cluster " << c;
  expectBoxPointsDynamicOthersStatic(window, result);
}

TEST(StaticScoreUpdate, MovingBoxPointsEndDynamicFromResidualsAlone) {
  // No depth evidence: the residuals condemn the box's points. Eq. 53 lets a dynamic point or a
  // dynamic cluster explain a residual, not both at no cost: with its points judged dynamic the box
  // cluster settles in between (only depth disagreement, its neighbours or tracking lower it).
  const BoxWindow window = boxWindow(false);
  const StaticScores result = solveFromAllStatic(window.problem);
  for (int c : {1, 2, 5, 6}) EXPECT_GT(result.gamma[static_cast<std::size_t>(c)], 0.75) << "cluster " << c;
  expectBoxPointsDynamicOthersStatic(window, result);
}

}  // namespace
}  // namespace ltlo::mapping
