// Synthetic bundle adjustment: convergence to the known solution, Schur vs full system,
// dense vs CHOLMOD, fixed vertices, marginal covariance against a dense inverse.
#include <gtest/gtest.h>

#include "synthetic_problems.h"

namespace sparse_opt {
namespace {

using testing::BaProblem;

constexpr int kCameras = 8;
constexpr int kPoints = 300;

struct Result {
  Summary summary;
  std::vector<SE3> poses;
  std::vector<Vec3> points;
};

Result solveBa(const BaProblem& problem, const Options& options, double huber_delta_px = 0.0) {
  Graph graph;
  testing::buildBaGraph(problem, graph, huber_delta_px);
  Result result;
  result.summary = graph.optimize(options);
  for (int k = 0; k < kCameras; ++k) result.poses.push_back(static_cast<VertexSE3*>(graph.vertex(k))->estimate());
  for (int j = 0; j < kPoints; ++j) {
    result.points.push_back(static_cast<VertexPoint3*>(graph.vertex(kCameras + j))->estimate());
  }
  return result;
}

double maxPoseDifference(const Result& a, const Result& b) {
  double d = 0.0;
  for (size_t k = 0; k < a.poses.size(); ++k) {
    d = std::max(d, (a.poses[k].translation() - b.poses[k].translation()).norm());
    d = std::max(d, testing::rotationDistanceRad(a.poses[k], b.poses[k]));
  }
  for (size_t j = 0; j < a.points.size(); ++j) d = std::max(d, (a.points[j] - b.points[j]).norm());
  return d;
}

Options tightOptions() {
  Options options;
  options.max_iterations = 50;
  options.function_tolerance = 1e-12;
  options.parameter_tolerance = 1e-12;
  return options;
}

TEST(BundleAdjustment, ConvergesToTruthWithinNoise) {
  const BaProblem problem = testing::makeBa(kCameras, kPoints, 8, /*noise_px=*/0.5, /*seed=*/1);
  const Result result = solveBa(problem, tightOptions());
  EXPECT_TRUE(result.summary.converged) << result.summary.termination;
  EXPECT_LT(result.summary.final_chi2, 0.01 * result.summary.initial_chi2);
  // chi2 of a converged problem with 0.5 px noise: about 0.25 px^2 per residual dimension left.
  const double num_residuals = 2.0 * problem.observations.size();
  EXPECT_LT(result.summary.final_chi2 / num_residuals, 0.25 * 1.2);
  double max_trans_err_m = 0.0, max_rot_err_rad = 0.0;
  for (int k = 0; k < kCameras; ++k) {
    max_trans_err_m = std::max(max_trans_err_m, (result.poses[k].translation() - problem.T_c_w_true[k].translation()).norm());
    max_rot_err_rad = std::max(max_rot_err_rad, testing::rotationDistanceRad(result.poses[k], problem.T_c_w_true[k]));
  }
  // Start was 0.05 m / 0.01 rad off; noise-limited accuracy is a few mm / 0.1 mrad here.
  EXPECT_LT(max_trans_err_m, 0.01);
  EXPECT_LT(max_rot_err_rad, 1e-3);
}

TEST(BundleAdjustment, SchurAndFullSystemAgree) {
  const BaProblem problem = testing::makeBa(kCameras, kPoints, 8, 0.5, 2);
  Options schur = tightOptions();
  schur.linear_solver = LinearSolverType::kCholmod;
  Options full = schur;
  full.use_schur = false;
  const Result a = solveBa(problem, schur);
  const Result b = solveBa(problem, full);
  EXPECT_TRUE(a.summary.used_schur);
  EXPECT_FALSE(b.summary.used_schur);
  EXPECT_EQ(b.summary.reduced_dimension, 6 * (kCameras - 2) + 3 * kPoints);
  EXPECT_LT(maxPoseDifference(a, b), 1e-8);
  EXPECT_NEAR(a.summary.final_chi2, b.summary.final_chi2, 1e-8 * a.summary.final_chi2);
}

TEST(BundleAdjustment, DenseAndCholmodAgree) {
  const BaProblem problem = testing::makeBa(kCameras, kPoints, 8, 0.5, 3);
  Options sparse = tightOptions();
  sparse.linear_solver = LinearSolverType::kCholmod;
  Options dense = sparse;
  dense.linear_solver = LinearSolverType::kDense;
  const Result a = solveBa(problem, sparse);
  const Result b = solveBa(problem, dense);
  EXPECT_TRUE(a.summary.used_cholmod);
  EXPECT_FALSE(b.summary.used_cholmod);
  EXPECT_LT(maxPoseDifference(a, b), 1e-8);
}

TEST(BundleAdjustment, ResultDoesNotDependOnThreadCount) {
  // Large enough (20,000 edges, 4,000 points) for the solver to actually use the second thread.
  const BaProblem problem = testing::makeBa(10, 4000, 5, 0.5, 4);
  auto solve = [&](int num_threads) {
    Graph graph;
    testing::buildBaGraph(problem, graph, 1.0);
    Options options;
    options.max_iterations = 4;
    options.num_threads = num_threads;
    graph.optimize(options);
    std::vector<double> values;
    for (int id = 0; id < 10 + 4000; ++id) {
      if (id < 10) {
        const SE3& T = static_cast<VertexSE3*>(graph.vertex(id))->estimate();
        values.insert(values.end(), T.rotation().coeffs().data(), T.rotation().coeffs().data() + 4);
        values.insert(values.end(), T.translation().data(), T.translation().data() + 3);
      } else {
        const Vec3& p = static_cast<VertexPoint3*>(graph.vertex(id))->estimate();
        values.insert(values.end(), p.data(), p.data() + 3);
      }
    }
    return values;
  };
  EXPECT_EQ(solve(1), solve(2));  // bit-identical
}

TEST(BundleAdjustment, FixedVerticesStayBitExact) {
  const BaProblem problem = testing::makeBa(kCameras, kPoints, 8, 0.5, 5);
  Graph graph;
  testing::buildBaGraph(problem, graph, 0.0, /*num_fixed=*/2, /*start_at_truth_for_fixed=*/false);
  static_cast<VertexPoint3*>(graph.vertex(kCameras + 7))->setFixed(true);
  const SE3 before0 = static_cast<VertexSE3*>(graph.vertex(0))->estimate();
  const SE3 before1 = static_cast<VertexSE3*>(graph.vertex(kCameras - 1))->estimate();
  const Vec3 point_before = static_cast<VertexPoint3*>(graph.vertex(kCameras + 7))->estimate();
  const Summary summary = graph.optimize(tightOptions());
  EXPECT_GT(summary.accepted_iterations, 0);
  for (const auto& [id, before] : {std::make_pair(0, before0), std::make_pair(kCameras - 1, before1)}) {
    const SE3& after = static_cast<VertexSE3*>(graph.vertex(id))->estimate();
    EXPECT_EQ(after.rotation().coeffs(), before.rotation().coeffs());
    EXPECT_EQ(after.translation(), before.translation());
  }
  EXPECT_EQ(static_cast<VertexPoint3*>(graph.vertex(kCameras + 7))->estimate(), point_before);
  EXPECT_NE(static_cast<VertexSE3*>(graph.vertex(2))->estimate().translation(), problem.T_c_w_init[2].translation());
}

TEST(BundleAdjustment, GaussNewtonConverges) {
  const BaProblem problem = testing::makeBa(kCameras, kPoints, 8, 0.5, 6);
  Options options = tightOptions();
  options.algorithm = Algorithm::kGaussNewton;
  const Result gn = solveBa(problem, options);
  const Result lm = solveBa(problem, tightOptions());
  EXPECT_LT(maxPoseDifference(gn, lm), 1e-6);
}

TEST(BundleAdjustment, SymbolicAnalysisReusedAcrossCalls) {
  const BaProblem problem = testing::makeBa(kCameras, kPoints, 8, 0.5, 7);
  Graph graph;
  testing::buildBaGraph(problem, graph, 0.0);
  Options options;
  options.linear_solver = LinearSolverType::kCholmod;
  options.max_iterations = 2;
  EXPECT_FALSE(graph.optimize(options).reused_symbolic);
  EXPECT_TRUE(graph.optimize(options).reused_symbolic);
  graph.removeVertex(kCameras + 5);  // a point: the camera pattern stays the same
  EXPECT_TRUE(graph.optimize(options).reused_symbolic);
  static_cast<VertexSE3*>(graph.vertex(4))->setFixed(true);  // the pattern shrinks
  EXPECT_FALSE(graph.optimize(options).reused_symbolic);
}

// A second optimize of an unchanged graph keeps the block structure and gives bit for bit what a
// graph built afresh at the same estimates gives; removing, fixing or freeing a vertex rebuilds it.
TEST(BundleAdjustment, StructureReusedOnlyWhileTheGraphIsUnchanged) {
  const BaProblem problem = testing::makeBa(kCameras, kPoints, 8, 0.5, 10);
  Options options;
  options.max_iterations = 3;
  Graph graph;
  testing::buildBaGraph(problem, graph, 1.0);
  EXPECT_FALSE(graph.optimize(options).reused_structure);
  // A fresh graph at the estimates the first call left.
  Graph fresh;
  testing::buildBaGraph(problem, fresh, 1.0);
  for (int k = 0; k < kCameras; ++k) {
    static_cast<VertexSE3*>(fresh.vertex(k))->setEstimate(static_cast<VertexSE3*>(graph.vertex(k))->estimate());
  }
  for (int j = 0; j < kPoints; ++j) {
    static_cast<VertexPoint3*>(fresh.vertex(kCameras + j))
        ->setEstimate(static_cast<VertexPoint3*>(graph.vertex(kCameras + j))->estimate());
  }
  const Summary again = graph.optimize(options);
  const Summary rebuilt = fresh.optimize(options);
  EXPECT_TRUE(again.reused_structure);
  EXPECT_FALSE(rebuilt.reused_structure);
  EXPECT_EQ(again.iterations, rebuilt.iterations);
  EXPECT_EQ(again.final_chi2, rebuilt.final_chi2);
  for (int k = 0; k < kCameras; ++k) {
    const SE3 a = static_cast<VertexSE3*>(graph.vertex(k))->estimate();
    const SE3 b = static_cast<VertexSE3*>(fresh.vertex(k))->estimate();
    EXPECT_EQ(a.translation(), b.translation()) << "camera " << k;
    EXPECT_EQ(a.rotation().coeffs(), b.rotation().coeffs()) << "camera " << k;
  }
  graph.removeVertex(kCameras + 5);  // a point and its edges
  EXPECT_FALSE(graph.optimize(options).reused_structure);
  EXPECT_TRUE(graph.optimize(options).reused_structure);
  // The same point made again (the allocator may hand out the freed addresses): rebuilt, or the new
  // vertex would keep a stale place in the system.
  {
    auto point = std::make_unique<VertexPoint3>(kCameras + 5, problem.p_w_init[5]);
    point->setMarginalized(true);
    VertexPoint3* added = graph.addVertex(std::move(point));
    for (const testing::BaObservation& obs : problem.observations) {
      if (obs.point != 5) continue;
      auto e = std::make_unique<EdgeProjectPoint>(problem.intrinsics);
      e->setVertex(0, graph.vertex(obs.camera));
      e->setVertex(1, added);
      e->setMeasurement(obs.uv_px);
      e->setRobustKernel(std::make_unique<HuberKernel>(1.0));
      graph.addEdge(std::move(e));
    }
  }
  EXPECT_FALSE(graph.optimize(options).reused_structure);
  EXPECT_TRUE(graph.optimize(options).reused_structure);
  graph.vertex(4)->setFixed(true);
  EXPECT_FALSE(graph.optimize(options).reused_structure);
  graph.vertex(4)->setFixed(false);
  EXPECT_FALSE(graph.optimize(options).reused_structure);
  graph.vertex(kCameras + 7)->setMarginalized(false);  // a point solved in the full system
  const Summary unmarginalised = graph.optimize(options);
  EXPECT_FALSE(unmarginalised.reused_structure);
  EXPECT_EQ(unmarginalised.reduced_dimension, 6 * (kCameras - 2) + 3);
}

TEST(BundleAdjustment, MarginalCovarianceMatchesDenseInverse) {
  const BaProblem problem = testing::makeBa(5, 40, 5, 0.5, 8);
  Graph graph;
  testing::buildBaGraph(problem, graph, 0.0, /*num_fixed=*/2);
  graph.optimize(tightOptions());
  // Dense H from the edges' own Jacobians: cameras 1..3 (6 each; 0 and 4 fixed), then points.
  const int nc = 3, np = 40, n = 6 * nc + 3 * np;
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
  for (EdgeBase* base : graph.edges()) {
    auto* e = static_cast<EdgeProjectPoint*>(base);
    e->computeError();
    e->linearizeOplus();
    const int cam = e->vertex(0)->id();
    const int pt = e->vertex(1)->id() - 5;
    Eigen::Matrix<double, 2, Eigen::Dynamic> J = Eigen::Matrix<double, 2, Eigen::Dynamic>::Zero(2, n);
    if (cam >= 1 && cam <= 3) J.middleCols<6>(6 * (cam - 1)) = e->jacobian<0>();
    J.middleCols<3>(6 * nc + 3 * pt) = e->jacobian<1>();
    H += J.transpose() * J;
  }
  const Eigen::MatrixXd H_inv = H.inverse();
  Options schur;
  schur.linear_solver = LinearSolverType::kCholmod;
  const std::vector<Eigen::MatrixXd> cov = graph.marginalCovariance({1, 3}, schur);
  ASSERT_EQ(cov.size(), 2u);
  EXPECT_LT((cov[0] - H_inv.block(0, 0, 6, 6)).norm(), 1e-9 * H_inv.block(0, 0, 6, 6).norm());
  EXPECT_LT((cov[1] - H_inv.block(12, 12, 6, 6)).norm(), 1e-9 * H_inv.block(12, 12, 6, 6).norm());
  Options dense;
  dense.linear_solver = LinearSolverType::kDense;
  const std::vector<Eigen::MatrixXd> point_cov = graph.marginalCovariance({5 + 3}, dense);  // a point: full system
  EXPECT_LT((point_cov[0] - H_inv.block(6 * nc + 9, 6 * nc + 9, 3, 3)).norm(), 1e-9 * point_cov[0].norm());
}

TEST(BundleAdjustment, HuberKeepsOutliersFromBiasing) {
  const BaProblem problem = testing::makeBa(kCameras, kPoints, 8, 0.5, 9, /*outlier_fraction=*/0.3);
  const Result plain = solveBa(problem, tightOptions());
  const Result huber = solveBa(problem, tightOptions(), /*huber_delta_px=*/1.0);
  // Huber bounds the pull of each outlier; a redescending Tukey round after it removes it.
  Graph graph;
  testing::buildBaGraph(problem, graph, /*huber_delta_px=*/1.0);
  graph.optimize(tightOptions());
  for (EdgeBase* e : graph.edges()) e->setRobustKernel(std::make_unique<TukeyKernel>(5.0));
  graph.optimize(tightOptions());
  Result robust;
  for (int j = 0; j < kPoints; ++j) robust.points.push_back(static_cast<VertexPoint3*>(graph.vertex(kCameras + j))->estimate());
  const Result clean = solveBa(testing::makeBa(kCameras, kPoints, 8, 0.5, 9, 0.0), tightOptions());
  auto meanPointError = [&](const Result& r) {
    double sum = 0.0;
    for (int j = 0; j < kPoints; ++j) sum += (r.points[j] - problem.p_w_true[j]).norm();
    return sum / kPoints;
  };
  EXPECT_LT(meanPointError(huber), 0.3 * meanPointError(plain));
  EXPECT_LT(meanPointError(robust), 1.5 * meanPointError(clean));
}

}  // namespace
}  // namespace sparse_opt
