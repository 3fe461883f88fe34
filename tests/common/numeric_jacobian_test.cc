// The shared numeric-Jacobian helper on functions with known derivatives: fixed and dynamic
// sizes, scalar output, and the manifold variant with a perturbation function.
#include "common/numeric_jacobian.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

namespace ltlo::test {
namespace {

TEST(NumericJacobian, FixedSizeMatchesAnalytic) {
  // f(x) = [x0 x1^2, sin(x2) + x0, exp(x1)]
  const Eigen::Vector3d x(0.7, -1.3, 0.4);
  const auto f = [](const Eigen::Vector3d& v) {
    return Eigen::Vector3d(v(0) * v(1) * v(1), std::sin(v(2)) + v(0), std::exp(v(1)));
  };
  Eigen::Matrix3d expected;
  expected << x(1) * x(1), 2.0 * x(0) * x(1), 0.0,  //
      1.0, 0.0, std::cos(x(2)),                     //
      0.0, std::exp(x(1)), 0.0;
  const Eigen::Matrix3d J = numericJacobian(f, x);
  EXPECT_LT((J - expected).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(NumericJacobian, NonSquareDynamicAndScalar) {
  // R^2 -> R^3 with dynamic sizes.
  Eigen::VectorXd x(2);
  x << 1.5, -0.5;
  const auto f = [](const Eigen::VectorXd& v) {
    Eigen::VectorXd y(3);
    y << v(0) + v(1), v(0) * v(1), v(1) * v(1);
    return y;
  };
  const Eigen::MatrixXd J = numericJacobian(f, x);
  ASSERT_EQ(J.rows(), 3);
  ASSERT_EQ(J.cols(), 2);
  Eigen::MatrixXd expected(3, 2);
  expected << 1.0, 1.0, x(1), x(0), 0.0, 2.0 * x(1);
  EXPECT_LT((J - expected).cwiseAbs().maxCoeff(), 1e-9);

  // Scalar output gives a 1 x n row: the gradient of x . x is 2 x.
  const Eigen::Vector2d y(0.3, -2.0);
  const Eigen::Matrix<double, 1, 2> g =
      numericJacobian([](const Eigen::Vector2d& v) { return v.dot(v); }, y);
  EXPECT_LT((g.transpose() - 2.0 * y).norm(), 1e-9);
}

TEST(NumericJacobian, ManifoldVariantUsesThePerturbation) {
  // "Manifold" = angle on the circle stored as a unit 2-vector, perturbed by rotation; f reads the
  // y coordinate, so df/ddelta = cos(theta).
  const double theta = 0.8;
  const Eigen::Vector2d point(std::cos(theta), std::sin(theta));
  const auto plus = [](const Eigen::Vector2d& p,
                       const Eigen::Matrix<double, 1, 1>& delta) -> Eigen::Vector2d {
    // Explicit return type: an `auto` lambda would return a product view of a dead temporary.
    return Eigen::Rotation2Dd(delta(0)).toRotationMatrix() * p;
  };
  const Eigen::Matrix<double, 1, 1> J =
      numericJacobianOnManifold<1>([](const Eigen::Vector2d& p) { return p.y(); }, point, plus);
  EXPECT_NEAR(J(0, 0), std::cos(theta), 1e-9);
}

}  // namespace
}  // namespace ltlo::test
