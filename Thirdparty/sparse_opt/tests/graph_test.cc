// Graph ownership, levels, and error messages for misuse.
#include <gtest/gtest.h>

#include <cmath>

#include "synthetic_problems.h"

namespace sparse_opt {
namespace {

std::string errorText(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(Graph, EdgeOnVertexNotInGraphIsRejected) {
  Graph graph;
  graph.addVertex(std::make_unique<VertexSE3>(0));
  VertexPoint3 outside(7);
  auto edge = std::make_unique<EdgeProjectPoint>(PinholeIntrinsics{});
  edge->setVertex(0, graph.vertex(0));
  edge->setVertex(1, &outside);
  const std::string text = errorText([&] { graph.addEdge(std::move(edge)); });
  EXPECT_NE(text.find("vertex 7 (slot 1) is not in the graph"), std::string::npos) << text;
  EXPECT_EQ(graph.numEdges(), 0u);
}

TEST(Graph, UnsetSlotDuplicateIdAndWrongTypeAreRejected) {
  Graph graph;
  graph.addVertex(std::make_unique<VertexSE3>(0));
  EXPECT_NE(errorText([&] { graph.addVertex(std::make_unique<VertexPoint3>(0)); }).find("vertex id 0 already"),
            std::string::npos);
  auto edge = std::make_unique<EdgeProjectPoint>(PinholeIntrinsics{});
  edge->setVertex(0, graph.vertex(0));
  EXPECT_NE(errorText([&] { graph.addEdge(std::move(edge)); }).find("vertex slot 1 is not set"), std::string::npos);
  EdgeProjectPoint wrong({});
  const std::string text = errorText([&] { wrong.setVertex(1, graph.vertex(0)); });
  EXPECT_NE(text.find("slot 1 cannot take vertex 0 of type sparse_opt::VertexSE3 (dimension 6)"), std::string::npos)
      << text;
}

TEST(Graph, NonFiniteResidualNamesTheEdge) {
  Graph graph;
  graph.addVertex(std::make_unique<VertexSE3>(0));
  auto* point = graph.addVertex(std::make_unique<VertexPoint3>(1, Vec3(0.0, 0.0, 0.0)));  // depth 0
  for (int k = 0; k < 3; ++k) {
    auto edge = std::make_unique<EdgeProjectPoint>(PinholeIntrinsics{500, 500, 320, 240});
    edge->setVertex(0, graph.vertex(0));
    edge->setVertex(1, point);
    graph.addEdge(std::move(edge));
  }
  const std::string text = errorText([&] { graph.optimize(); });
  EXPECT_NE(text.find("edge 0 (sparse_opt::EdgeProjectPoint) has a non-finite residual"), std::string::npos) << text;
}

TEST(Graph, SchurRejectsEdgeBetweenTwoLandmarks) {
  class EdgeTwoPoints final : public BaseEdge<3, Vec3, VertexPoint3, VertexPoint3> {
   public:
    void computeError() override { error_ = estimate<0>() - estimate<1>() - measurement_; }
  };
  Graph graph;
  for (int id = 0; id < 2; ++id) graph.addVertex(std::make_unique<VertexPoint3>(id))->setMarginalized(true);
  auto edge = std::make_unique<EdgeTwoPoints>();
  edge->setVertex(0, graph.vertex(0));
  edge->setVertex(1, graph.vertex(1));
  graph.addEdge(std::move(edge));
  EXPECT_NE(errorText([&] { graph.optimize(); }).find("connects more than one marginalized vertex"),
            std::string::npos);
  Options no_schur;
  no_schur.use_schur = false;
  static_cast<VertexPoint3*>(graph.vertex(0))->setFixed(true);
  EXPECT_TRUE(graph.optimize(no_schur).converged);
}

TEST(Graph, LevelsSwitchEdgesOffAndChi2IsReadable) {
  Graph graph;
  auto* v = graph.addVertex(std::make_unique<VertexVector<2>>(0, Eigen::Vector2d(5.0, 5.0)));
  class EdgeVec2Prior final : public BaseEdge<2, Eigen::Vector2d, VertexVector<2>> {
   public:
    void computeError() override { error_ = estimate<0>() - measurement_; }
  };
  for (double target : {1.0, 3.0, 100.0}) {
    auto e = std::make_unique<EdgeVec2Prior>();
    e->setVertex(0, v);
    e->setMeasurement(Eigen::Vector2d(target, target));
    graph.addEdge(std::move(e));
  }
  graph.edges()[2]->setLevel(1);  // the "outlier" is switched off, not removed
  graph.optimize();
  EXPECT_NEAR(v->estimate().x(), 2.0, 1e-6);
  EXPECT_NEAR(graph.edges()[0]->chi2(), 2.0, 1e-6);
  EXPECT_NEAR(graph.edges()[2]->chi2(), 2.0 * 98.0 * 98.0, 1e-3);  // evaluated though inactive
  graph.removeEdge(graph.edges()[0]);
  graph.optimize();
  EXPECT_NEAR(v->estimate().x(), 3.0, 1e-6);
  graph.removeVertex(0);
  EXPECT_EQ(graph.numEdges(), 0u);
  EXPECT_EQ(graph.numVertices(), 0u);
}

TEST(Graph, UserVertexWithCustomManifold) {
  // Scalar on the positive reals, updated multiplicatively.
  class VertexScale final : public BaseVertex<1, double> {
   public:
    using BaseVertex::BaseVertex;
    double plus(const double& x, const Delta& d) const override { return x * std::exp(d[0]); }
  };
  class EdgeScale final : public BaseEdge<1, double, VertexScale> {
   public:
    void computeError() override { error_[0] = std::log(estimate<0>()) - std::log(measurement_); }
  };
  Graph graph;
  auto* s = graph.addVertex(std::make_unique<VertexScale>(0, 10.0));
  auto e = std::make_unique<EdgeScale>();
  e->setVertex(0, s);
  e->setMeasurement(2.0);
  graph.addEdge(std::move(e));
  const Summary summary = graph.optimize();
  EXPECT_NEAR(s->estimate(), 2.0, 1e-6);
  EXPECT_LT(summary.final_chi2, 1e-12);
}

}  // namespace
}  // namespace sparse_opt

namespace sparse_opt {
namespace {

TEST(Graph, So3VertexAveragesRotations) {
  // User edge on the provided SO3 vertex, numeric Jacobians: error = Log(Z^-1 q).
  class EdgeRotationPrior final : public BaseEdge<3, Quat, VertexSO3> {
   public:
    void computeError() override { error_ = so3Log(measurement_.conjugate() * estimate<0>()); }
  };
  const Quat base = so3Exp(Vec3(0.3, -0.2, 1.0));
  Graph graph;
  auto* q = graph.addVertex(std::make_unique<VertexSO3>(0, Quat::Identity()));
  for (const Vec3& offset : std::vector<Vec3>{Vec3(0.01, 0, 0), Vec3(-0.01, 0, 0), Vec3(0, 0.02, 0), Vec3(0, -0.02, 0)}) {
    auto e = std::make_unique<EdgeRotationPrior>();
    e->setVertex(0, q);
    e->setMeasurement(base * so3Exp(offset));
    graph.addEdge(std::move(e));
  }
  Options options;
  options.function_tolerance = 1e-12;
  graph.optimize(options);
  EXPECT_LT(so3Log(base.conjugate() * q->estimate()).norm(), 1e-5);
}


// x measured as a value: residual x - m (one dimension).
class EdgeValue final : public BaseEdge<1, double, VertexVector<1>> {
 public:
  void computeError() override { error_[0] = estimate<0>()[0] - measurement_; }
  void linearizeOplus() override { jacobian<0>()(0, 0) = 1.0; }
};

TEST(Graph, CostScaleWeighsTheEdgeNotTheKernelArgument) {
  // Without kernels: w1 (x - 1)^2 + w2 (x - 4)^2 is minimal at the weighted mean.
  Graph graph;
  auto* x = graph.addVertex(std::make_unique<VertexVector<1>>(0, Eigen::Matrix<double, 1, 1>(0.0)));
  EdgeValue* edges[2];
  const double measurements[2] = {1.0, 4.0};
  for (int k = 0; k < 2; ++k) {
    auto edge = std::make_unique<EdgeValue>();
    edge->setVertex(0, x);
    edge->setMeasurement(measurements[k]);
    edges[k] = graph.addEdge(std::move(edge));
  }
  edges[0]->setCostScale(3.0);
  edges[1]->setCostScale(1.0);
  Options options;
  options.algorithm = Algorithm::kGaussNewton;
  graph.optimize(options);
  EXPECT_NEAR(x->estimate()[0], (3.0 * 1.0 + 1.0 * 4.0) / 4.0, 1e-9);
  EXPECT_NEAR(edges[0]->robustChi2(), 3.0 * edges[0]->chi2(), 1e-12);  // chi2() stays unweighted

  // With Huber (delta 1) on both: the kink stays at |e| = 1 whatever the scale, so at the optimum
  // the scaled gradients balance: w1 rho'(s1) e1 = -w2 rho'(s2) e2. With w1 = 3, w2 = 1 and both
  // residuals beyond the kink: 3 sign(e1) = -sign(e2) cannot hold, so x sits where edge 0 is
  // inside its kink: 3 e1 = 1 (edge 1's Huber gradient magnitude is delta = 1), e1 = 1/3.
  for (EdgeValue* e : edges) e->setRobustKernel(std::make_unique<HuberKernel>(1.0));
  x->setEstimate(Eigen::Matrix<double, 1, 1>(2.5));
  options.max_iterations = 200;  // IRLS on Huber converges linearly: run to the tolerance floor
  options.function_tolerance = 1e-15;
  options.parameter_tolerance = 1e-15;
  graph.optimize(options);
  EXPECT_NEAR(x->estimate()[0], 1.0 + 1.0 / 3.0, 1e-6);
  EXPECT_NEAR(edges[0]->robustChi2(), 3.0 * (1.0 / 9.0), 1e-6);
  EXPECT_NEAR(edges[1]->robustChi2(), 1.0 * (2.0 * std::sqrt(edges[1]->chi2()) - 1.0), 1e-9);

  EXPECT_NE(errorText([&] { edges[0]->setCostScale(-1.0); }).find("setCostScale: scale -1"), std::string::npos);
}

// x^2 measured (residual x^2 - m), counting the solver's calls.
class EdgeSquareCounting final : public BaseEdge<1, double, VertexVector<1>> {
 public:
  void computeError() override {
    ++compute_error_calls;
    error_[0] = estimate<0>()[0] * estimate<0>()[0] - measurement_;
  }
  void linearizeOplus() override {
    ++linearize_calls;
    jacobian<0>()(0, 0) = 2.0 * estimate<0>()[0];
  }
  int compute_error_calls = 0;
  int linearize_calls = 0;
};

TEST(Graph, TheSolverLinearisesAtTheResidualItJustEvaluated) {
  // Every linearisation follows a chi2 evaluation at the same estimates, so the residual is computed
  // once per evaluation: at the start and after each step; the end needs none when the last step was
  // kept (none is rejected under Gauss-Newton, none cut short by the parameter or gradient tolerance
  // at 0).
  Graph graph;
  auto* x = graph.addVertex(std::make_unique<VertexVector<1>>(0, Eigen::Matrix<double, 1, 1>(3.0)));
  auto edge = std::make_unique<EdgeSquareCounting>();
  edge->setVertex(0, x);
  edge->setMeasurement(2.0);
  EdgeSquareCounting* counted = graph.addEdge(std::move(edge));
  Options options;
  options.algorithm = Algorithm::kGaussNewton;
  options.max_iterations = 50;
  options.function_tolerance = 1e-14;
  options.parameter_tolerance = 0.0;
  options.gradient_tolerance = 0.0;
  const Summary summary = graph.optimize(options);
  EXPECT_NEAR(x->estimate()[0], std::sqrt(2.0), 1e-9);
  ASSERT_GE(summary.iterations, 4);  // Newton from 3 to sqrt(2): several linearisations
  EXPECT_EQ(counted->compute_error_calls, summary.iterations + 1);
  EXPECT_EQ(counted->linearize_calls, summary.iterations);  // the last step ends on the tolerance
  EXPECT_NEAR(counted->chi2(), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(summary.final_chi2, counted->robustChi2());

  // A rejected last trial (LM from a start whose first step overshoots, one iteration) is rolled
  // back, and the end evaluates the kept estimate again: chi2() describes it.
  x->setEstimate(Eigen::Matrix<double, 1, 1>(0.05));
  counted->compute_error_calls = 0;
  options.algorithm = Algorithm::kLevenbergMarquardt;
  options.initial_lambda = 1e-12;
  options.max_iterations = 1;
  const Summary rejected = graph.optimize(options);
  ASSERT_EQ(rejected.accepted_iterations, 0);
  EXPECT_EQ(x->estimate()[0], 0.05);
  EXPECT_EQ(counted->compute_error_calls, 3);  // start, the trial, the kept estimate again
  EXPECT_DOUBLE_EQ(counted->chi2(), std::pow(0.05 * 0.05 - 2.0, 2));
  EXPECT_DOUBLE_EQ(rejected.final_chi2, rejected.initial_chi2);
}

}  // namespace
}  // namespace sparse_opt
