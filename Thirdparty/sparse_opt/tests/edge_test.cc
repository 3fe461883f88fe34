// Analytic Jacobians of the provided edges against central differences.
#include <gtest/gtest.h>

#include <random>

#include "synthetic_problems.h"

namespace sparse_opt {
namespace {

using testing::perturb;

template <class E>
void expectAnalyticMatchesNumeric(E& edge, double tolerance) {
  edge.computeError();
  edge.linearizeOplus();
  const auto analytic = std::make_tuple(edge.template jacobian<0>(),
                                        edge.template jacobian<E::kNumVertices - 1>());
  edge.numericJacobians();
  EXPECT_LT((std::get<0>(analytic) - edge.template jacobian<0>()).norm(), tolerance)
      << "analytic\n" << std::get<0>(analytic) << "\nnumeric\n" << edge.template jacobian<0>();
  EXPECT_LT((std::get<1>(analytic) - edge.template jacobian<E::kNumVertices - 1>()).norm(), tolerance)
      << "analytic\n" << std::get<1>(analytic) << "\nnumeric\n" << edge.template jacobian<E::kNumVertices - 1>();
}

TEST(EdgeJacobians, ProjectPoint) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 5; ++trial) {
    VertexSE3 pose(0, perturb(SE3(), rng, 0.3, 0.5));
    VertexPoint3 point(1, pose.estimate().inverse() * Vec3(0.5, -0.3, 4.0) + testing::randomVec3(rng, 0.2));
    EdgeProjectPoint edge({500.0, 480.0, 320.0, 240.0});
    edge.setVertex(0, &pose);
    edge.setVertex(1, &point);
    edge.setMeasurement(Vec2(300.0, 200.0));
    expectAnalyticMatchesNumeric(edge, 1e-5);
  }
}

TEST(EdgeJacobians, Se3RelativeWithLargeResidual) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 5; ++trial) {
    VertexSE3 a(0, perturb(SE3(), rng, 0.8, 2.0));
    VertexSE3 b(1, perturb(SE3(), rng, 0.8, 2.0));
    EdgeSE3Relative edge;
    edge.setVertex(0, &a);
    edge.setVertex(1, &b);
    // Measurement far from a^-1 b: residual rotation of about 0.5 rad.
    edge.setMeasurement(perturb(a.estimate().inverse() * b.estimate(), rng, 0.3, 1.0));
    expectAnalyticMatchesNumeric(edge, 1e-6);
  }
}

TEST(EdgeJacobians, Se3Prior) {
  std::mt19937 rng(9);
  for (int trial = 0; trial < 5; ++trial) {
    VertexSE3 pose(0, perturb(SE3(), rng, 0.8, 2.0));
    EdgeSE3Prior edge;
    edge.setVertex(0, &pose);
    edge.setMeasurement(perturb(pose.estimate(), rng, 0.3, 1.0));
    expectAnalyticMatchesNumeric(edge, 1e-6);
  }
}

// A user-defined edge without analytic Jacobians uses central differences automatically.
class EdgePointDistance final : public BaseEdge<1, double, VertexPoint3, VertexPoint3> {
 public:
  void computeError() override { error_[0] = (estimate<0>() - estimate<1>()).norm() - measurement_; }
};

TEST(EdgeJacobians, NumericFallbackForUserEdge) {
  VertexPoint3 a(0, Vec3(1.0, 2.0, 3.0));
  VertexPoint3 b(1, Vec3(-1.0, 0.5, 2.0));
  EdgePointDistance edge;
  edge.setVertex(0, &a);
  edge.setVertex(1, &b);
  edge.setMeasurement(1.0);
  edge.computeError();
  edge.linearizeOplus();
  const Vec3 direction = (a.estimate() - b.estimate()).normalized();
  EXPECT_LT((edge.jacobian<0>().transpose() - direction).norm(), 1e-8);
  EXPECT_LT((edge.jacobian<1>().transpose() + direction).norm(), 1e-8);
  // The vertices themselves were never perturbed.
  EXPECT_EQ(a.estimate(), Vec3(1.0, 2.0, 3.0));
}

TEST(RobustKernels, DerivativesMatchNumeric) {
  const HuberKernel huber(1.5);
  const CauchyKernel cauchy(1.5);
  const TukeyKernel tukey(1.5);
  for (const RobustKernel* k : std::vector<const RobustKernel*>{&huber, &cauchy, &tukey}) {
    for (double s : {0.3, 1.0, 2.0, 5.0}) {
      const double h = 1e-6;
      const double numeric = (k->evaluate(s + h)[0] - k->evaluate(s - h)[0]) / (2 * h);
      EXPECT_NEAR(k->evaluate(s)[1], numeric, 1e-6) << "s = " << s;
    }
  }
  EXPECT_DOUBLE_EQ(huber.evaluate(1.0)[0], 1.0);       // quadratic inside delta
  EXPECT_DOUBLE_EQ(huber.evaluate(9.0)[0], 2 * 1.5 * 3 - 2.25);
  EXPECT_DOUBLE_EQ(tukey.evaluate(100.0)[1], 0.0);     // outliers get zero weight
}

}  // namespace
}  // namespace sparse_opt
