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
