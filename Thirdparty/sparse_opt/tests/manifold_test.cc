#include "sparse_opt/manifold.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace sparse_opt {
namespace {

TEST(Manifold, ExpLogRoundTripNearZeroAndPi) {
  for (const Vec3& phi : std::vector<Vec3>{Vec3(1e-10, -2e-10, 0.0), Vec3(0.3, -0.2, 0.1), Vec3(0.0, 0.0, M_PI - 1e-6),
                          Vec3(1.0, 2.0, -0.5).normalized() * 3.0}) {
    EXPECT_LT((so3Log(so3Exp(phi)) - phi).norm(), 1e-9) << phi.transpose();
  }
}

TEST(Manifold, RightJacobianInverseMatchesNumericLog) {
  const Vec3 phi(0.4, -0.7, 0.2);
  const Mat3 jr_inv = so3RightJacobianInverse(phi);
  EXPECT_LT((jr_inv * so3RightJacobian(phi) - Mat3::Identity()).norm(), 1e-12);
  Mat3 numeric;
  const double h = 1e-6;
  for (int k = 0; k < 3; ++k) {
    const Vec3 d = Vec3::Unit(k) * h;
    numeric.col(k) = (so3Log(so3Exp(phi) * so3Exp(d)) - so3Log(so3Exp(phi) * so3Exp(-d))) / (2 * h);
  }
  EXPECT_LT((numeric - jr_inv).norm(), 1e-8);
}

TEST(Manifold, Se3ExpMatchesMatrixSeries) {
  Vec6 xi;
  xi << 0.2, -0.1, 0.3, 1.0, -2.0, 0.5;
  Eigen::Matrix4d twist = Eigen::Matrix4d::Zero();
  twist.topLeftCorner<3, 3>() = hat(xi.head<3>());
  twist.topRightCorner<3, 1>() = xi.tail<3>();
  Eigen::Matrix4d expm = Eigen::Matrix4d::Identity(), term = Eigen::Matrix4d::Identity();
  for (int n = 1; n < 30; ++n) {
    term = term * twist / n;
    expm += term;
  }
  const SE3 T = SE3::exp(xi);
  EXPECT_LT((T.rotationMatrix() - expm.topLeftCorner<3, 3>()).norm(), 1e-12);
  EXPECT_LT((T.translation() - expm.topRightCorner<3, 1>()).norm(), 1e-12);
}

}  // namespace
}  // namespace sparse_opt
