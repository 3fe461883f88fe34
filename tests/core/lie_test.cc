// Lie-group helpers (include/ltlo/core/lie.h): every Jacobian against central differences,
// exp/log round trips near 0 and near pi, adjoint identity, Sim3 algebra, re-orthonormalisation.
#include "ltlo/core/lie.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "common/numeric_jacobian.h"

namespace ltlo {
namespace {

// Rotation angles that exercise every branch: exact zero, the Taylor branches (< 1e-2 rad), both
// sides of the switch, generic angles and the neighbourhood of pi where log changes sheet.
const std::vector<double> kAngles = {0.0, 1e-12, 1e-9, 1e-5, 1e-3,        0.0099999,   0.0100001,
                                     0.3, 1.0,   2.0,  3.0,  M_PI - 1e-3, M_PI - 1e-6, M_PI - 1e-9};

// Fixed unit axes, including one along a coordinate axis (Eigen's matrix->quaternion branches).
const std::vector<Vec3> kAxes = {Vec3(1.0, -2.0, 0.5).normalized(), Vec3(0.0, 0.0, 1.0),
                                 Vec3(-0.3, 0.9, 0.2).normalized()};

Vec3 randomUnit(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Vec3(n(rng), n(rng), n(rng)).normalized();
}

double maxAbs(const MatX& m) { return m.cwiseAbs().maxCoeff(); }

// ---- hat / vee ------------------------------------------------------------------------------

TEST(So3, HatIsCrossProductAndVeeInvertsIt) {
  const Vec3 v(0.3, -1.2, 2.5);
  const Vec3 w(-0.7, 0.4, 1.1);
  EXPECT_LT((hat(v) * w - v.cross(w)).norm(), 1e-15);
  EXPECT_LT((hat(v) + hat(v).transpose()).norm(), 1e-15);
  EXPECT_LT((vee(hat(v)) - v).norm(), 1e-15);
}

// ---- SO3 exp / log --------------------------------------------------------------------------

TEST(So3, LogOfExpRecoversRotationVector) {
  for (const Vec3& axis : kAxes) {
    for (const double angle : kAngles) {
      const Vec3 phi = angle * axis;
      // Absolute error: near pi the quaternion's w ~ 1e-9 still gives the angle to ~1e-15 via
      // atan2.
      EXPECT_LT((so3Log(so3Exp(phi)) - phi).norm(), 1e-10) << "angle " << angle;
      EXPECT_LT((so3Log(so3ExpQuat(phi)) - phi).norm(), 1e-12) << "angle " << angle;
      if (angle > 0.0 && angle < 1e-3) {
        EXPECT_LT((so3Log(so3Exp(phi)) - phi).norm() / angle, 1e-9) << "relative, angle " << angle;
      }
    }
  }
}

TEST(So3, ExpOfLogRecoversRotation) {
  std::mt19937 rng(11);
  for (int i = 0; i < 50; ++i) {
    const Vec3 axis = randomUnit(rng);
    for (const double angle : kAngles) {
      const Mat3 R = so3Exp(angle * axis);
      EXPECT_LT((so3Exp(so3Log(R)) - R).norm(), 1e-12) << "angle " << angle;
    }
  }
}

TEST(So3, LogAtExactlyPiGivesAngleOfPi) {
  for (const Vec3& axis : kAxes) {
    Mat3 R = 2.0 * axis * axis.transpose() - Mat3::Identity();  // rotation by pi about axis
    const Vec3 phi = so3Log(R);
    EXPECT_NEAR(phi.norm(), M_PI, 1e-12);
    EXPECT_NEAR(std::abs(phi.normalized().dot(axis)), 1.0, 1e-12);  // either sign is the same R
    EXPECT_LT((so3Exp(phi) - R).norm(), 1e-12);
  }
}

TEST(So3, ExpMatchesRodriguesAndStaysOrthonormal) {
  const Vec3 phi(0.4, -0.2, 0.9);
  const double theta = phi.norm();
  const Mat3 K = hat(phi / theta);
  const Mat3 rodrigues = Mat3::Identity() + std::sin(theta) * K + (1.0 - std::cos(theta)) * K * K;
  EXPECT_LT((so3Exp(phi) - rodrigues).norm(), 1e-14);
  EXPECT_LT((so3Exp(phi).transpose() * so3Exp(phi) - Mat3::Identity()).norm(), 1e-14);
  EXPECT_GE(so3ExpQuat(-3.0 * Vec3::UnitX()).w(), 0.0);
}

// ---- SO3 Jacobians --------------------------------------------------------------------------

// Jacobians are checked where log stays on one sheet under the eps step, so the largest angle is
// pi - 1e-4 (with a step of 1e-7, well below the distance to pi).
const std::vector<double> kJacobianAngles = {0.0,       1e-9, 1e-5, 1e-3, 0.0099999,
                                             0.0100001, 0.5,  1.5,  2.5,  M_PI - 1e-4};

TEST(So3Jacobian, RightJacobianMatchesNumeric) {
  // Exp(phi + d) = Exp(phi) Exp(J_r(phi) d)  =>  J_r = d/dd Log(Exp(phi)^T Exp(phi + d)).
  for (const Vec3& axis : kAxes) {
    for (const double angle : kJacobianAngles) {
      const Vec3 phi = angle * axis;
      const Mat3 R_t = so3Exp(phi).transpose();
      const Mat3 J = test::numericJacobian(
          [&](const Vec3& p) { return so3Log(Mat3(R_t * so3Exp(p))); }, phi, 1e-7);
      EXPECT_LT(maxAbs(so3RightJacobian(phi) - J), 2e-7) << "angle " << angle;
    }
  }
}

TEST(So3Jacobian, LeftJacobianMatchesNumeric) {
  // Exp(phi + d) = Exp(J_l(phi) d) Exp(phi).
  for (const Vec3& axis : kAxes) {
    for (const double angle : kJacobianAngles) {
      const Vec3 phi = angle * axis;
      const Mat3 R_t = so3Exp(phi).transpose();
      const Mat3 J = test::numericJacobian(
          [&](const Vec3& p) { return so3Log(Mat3(so3Exp(p) * R_t)); }, phi, 1e-7);
      EXPECT_LT(maxAbs(so3LeftJacobian(phi) - J), 2e-7) << "angle " << angle;
    }
  }
}

TEST(So3Jacobian, InverseJacobiansMatchNumeric) {
  // Log(Exp(phi) Exp(d)) = phi + J_r^-1(phi) d;  Log(Exp(d) Exp(phi)) = phi + J_l^-1(phi) d.
  for (const Vec3& axis : kAxes) {
    for (const double angle : kJacobianAngles) {
      const Vec3 phi = angle * axis;
      const Mat3 R = so3Exp(phi);
      const Mat3 Jr_inv = test::numericJacobian(
          [&](const Vec3& d) { return so3Log(Mat3(R * so3Exp(d))); }, Vec3::Zero(), 1e-7);
      const Mat3 Jl_inv = test::numericJacobian(
          [&](const Vec3& d) { return so3Log(Mat3(so3Exp(d) * R)); }, Vec3::Zero(), 1e-7);
      // Near pi J^-1 grows like 1 / (pi - angle) (~1e4 here); compare relative to its size.
      const double scale = std::max(1.0, maxAbs(so3RightJacobianInverse(phi)));
      EXPECT_LT(maxAbs(so3RightJacobianInverse(phi) - Jr_inv) / scale, 2e-6) << "angle " << angle;
      EXPECT_LT(maxAbs(so3LeftJacobianInverse(phi) - Jl_inv) / scale, 2e-6) << "angle " << angle;
      EXPECT_LT(maxAbs(so3RightJacobian(phi) * so3RightJacobianInverse(phi) - Mat3::Identity()),
                1e-12 * scale)
          << "angle " << angle;
      EXPECT_LT(maxAbs(so3LeftJacobian(phi) * so3LeftJacobianInverse(phi) - Mat3::Identity()),
                1e-12 * scale)
          << "angle " << angle;
    }
  }
}

TEST(So3Jacobian, LeftIsRotatedRight) {
  // J_l(phi) = Exp(phi) J_r(phi).
  const Vec3 phi(0.7, -1.1, 0.4);
  EXPECT_LT(maxAbs(so3LeftJacobian(phi) - so3Exp(phi) * so3RightJacobian(phi)), 1e-14);
}

// ---- normalizeRotation / normalizeQuat ------------------------------------------------------

TEST(So3, NormalizeRotationProjectsPerturbedMatrix) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1e-3);
  for (int i = 0; i < 20; ++i) {
    const Mat3 R = so3Exp(2.0 * randomUnit(rng));
    Mat3 drifted = R;
    for (int k = 0; k < 9; ++k) drifted(k / 3, k % 3) += noise(rng);
    const Mat3 R_fixed = normalizeRotation(drifted);
    EXPECT_LT((R_fixed.transpose() * R_fixed - Mat3::Identity()).norm(), 1e-14);
    EXPECT_NEAR(R_fixed.determinant(), 1.0, 1e-14);
    // The projection moves by at most the drift (1e-3 per element, 9 elements).
    EXPECT_LT((R_fixed - R).norm(), 1e-2);
    // It is the nearest rotation: closer to the drifted matrix than the original rotation.
    EXPECT_LE((R_fixed - drifted).norm(), (R - drifted).norm() + 1e-15);
  }
  const Mat3 R = so3Exp(Vec3(0.1, 0.2, -0.3));
  EXPECT_LT((normalizeRotation(1.05 * R) - R).norm(), 1e-14);  // uniform scale removed
  EXPECT_LT((normalizeRotation(R) - R).norm(), 1e-14);
}

TEST(So3, NormalizeQuatGivesUnitNonNegativeW) {
  const Quat q = normalizeQuat(Quat(-2.0, 0.2, -0.4, 1.0));
  EXPECT_NEAR(q.norm(), 1.0, 1e-15);
  EXPECT_GE(q.w(), 0.0);
  EXPECT_LT(
      (q.toRotationMatrix() - Quat(-2.0, 0.2, -0.4, 1.0).normalized().toRotationMatrix()).norm(),
      1e-15);
}

// ---- SE3 ------------------------------------------------------------------------------------

Vec6 twist(const Vec3& phi, const Vec3& rho) {
  Vec6 xi;
  xi << phi, rho;
  return xi;
}

TEST(Se3, LogOfExpRecoversTwist) {
  const Vec3 rho(0.4, -1.3, 2.2);
  for (const Vec3& axis : kAxes) {
    for (const double angle : kAngles) {
      const Vec6 xi = twist(angle * axis, rho);
      // Measured ~1e-15 everywhere, near pi included.
      EXPECT_LT((SE3::exp(xi).log() - xi).norm(), 1e-12) << "angle " << angle;
    }
  }
}

TEST(Se3, ExpOfLogRecoversTransform) {
  std::mt19937 rng(5);
  for (int i = 0; i < 30; ++i) {
    for (const double angle : kAngles) {
      const SE3 T(so3ExpQuat(angle * randomUnit(rng)), 3.0 * randomUnit(rng));
      const SE3 back = SE3::exp(T.log());
      EXPECT_LT((back.matrix() - T.matrix()).norm(), 1e-9) << "angle " << angle;
    }
  }
}

TEST(Se3, ExpOfPureTranslationAndPureRotation) {
  const Vec3 rho(1.0, 2.0, 3.0);
  EXPECT_LT((SE3::exp(twist(Vec3::Zero(), rho)).translation() - rho).norm(), 1e-15);
  const Vec3 phi(0.2, 0.3, -0.1);
  const SE3 T = SE3::exp(twist(phi, Vec3::Zero()));
  EXPECT_LT((T.rotationMatrix() - so3Exp(phi)).norm(), 1e-15);
  EXPECT_LT(T.translation().norm(), 1e-15);
}

TEST(Se3, ExpMatchesMatrixExponentialSeries) {
  // exp of the 4x4 twist matrix [phi^ rho; 0 0] by its (converging) power series.
  const Vec6 xi = twist(Vec3(0.5, -0.8, 0.3), Vec3(1.0, -0.5, 2.0));
  Mat4 A = Mat4::Zero();
  A.block<3, 3>(0, 0) = hat(xi.head<3>());
  A.block<3, 1>(0, 3) = xi.tail<3>();
  Mat4 term = Mat4::Identity();
  Mat4 series = Mat4::Identity();
  for (int k = 1; k < 40; ++k) {
    term = term * A / k;
    series += term;
  }
  EXPECT_LT((SE3::exp(xi).matrix() - series).norm(), 1e-13);
}

TEST(Se3, ComposeInverseAndMatrixAgree) {
  const SE3 T_a_b(so3ExpQuat(Vec3(0.1, 0.7, -0.2)), Vec3(1.0, 2.0, -0.5));
  const SE3 T_b_c(so3ExpQuat(Vec3(-0.4, 0.1, 0.9)), Vec3(-0.3, 0.2, 1.5));
  const Vec3 p_c(0.3, -0.6, 2.0);
  EXPECT_LT(((T_a_b * T_b_c).matrix() - T_a_b.matrix() * T_b_c.matrix()).norm(), 1e-14);
  EXPECT_LT(((T_a_b * T_b_c) * p_c - T_a_b * (T_b_c * p_c)).norm(), 1e-14);
  EXPECT_LT((T_a_b.inverse() * T_a_b).log().norm(), 1e-15);
  EXPECT_LT((T_a_b.inverse().matrix() - T_a_b.matrix().inverse()).norm(), 1e-14);
  EXPECT_LT((SE3::fromMatrix(T_a_b.matrix()).matrix() - T_a_b.matrix()).norm(), 1e-15);
  EXPECT_LT((T_a_b.matrix3x4() - T_a_b.matrix().topRows<3>()).norm(), 1e-15);
}

TEST(Se3, AdjointConjugatesTwists) {
  std::mt19937 rng(9);
  for (int i = 0; i < 20; ++i) {
    const SE3 T(so3ExpQuat(2.5 * randomUnit(rng)), 2.0 * randomUnit(rng));
    const Vec6 xi = twist(0.8 * randomUnit(rng), 1.5 * randomUnit(rng));
    const SE3 lhs = T * SE3::exp(xi) * T.inverse();
    const SE3 rhs = SE3::exp(T.adjoint() * xi);
    EXPECT_LT((lhs.matrix() - rhs.matrix()).norm(), 1e-13);
    // And as a Jacobian: d/dxi log(T exp(xi) T^-1) at 0 is Ad(T).
    const Mat6 J = test::numericJacobian(
        [&](const Vec6& x) { return (T * SE3::exp(x) * T.inverse()).log(); }, Vec6::Zero().eval());
    EXPECT_LT(maxAbs(T.adjoint() - J), 1e-8);
  }
}

// The SE3 Jacobians involve the Q(phi, rho) block; check them at generic poses and near the
// Taylor switch (|phi| = 1e-2) and near pi, for large and small translations.
std::vector<Vec6> se3JacobianTwists() {
  std::vector<Vec6> twists;
  for (const double angle : kJacobianAngles) {
    twists.push_back(twist(angle * kAxes[0], Vec3(0.5, -1.0, 2.0)));
    twists.push_back(twist(angle * kAxes[2], Vec3(-0.02, 0.01, 0.03)));
  }
  return twists;
}

TEST(Se3Jacobian, LeftJacobianMatchesNumeric) {
  // exp(xi + d) = exp(J_l(xi) d) exp(xi)  =>  J_l = d/dd log(exp(xi + d) exp(xi)^-1).
  for (const Vec6& xi : se3JacobianTwists()) {
    const SE3 T_inv = SE3::exp(xi).inverse();
    const Mat6 J =
        test::numericJacobian([&](const Vec6& x) { return (SE3::exp(x) * T_inv).log(); }, xi, 1e-7);
    EXPECT_LT(maxAbs(se3LeftJacobian(xi) - J), 1e-6) << xi.transpose();
  }
}

TEST(Se3Jacobian, RightJacobianMatchesNumeric) {
  // exp(xi + d) = exp(xi) exp(J_r(xi) d).
  for (const Vec6& xi : se3JacobianTwists()) {
    const SE3 T_inv = SE3::exp(xi).inverse();
    const Mat6 J =
        test::numericJacobian([&](const Vec6& x) { return (T_inv * SE3::exp(x)).log(); }, xi, 1e-7);
    EXPECT_LT(maxAbs(se3RightJacobian(xi) - J), 1e-6) << xi.transpose();
  }
}

TEST(Se3Jacobian, InverseJacobiansMatchNumeric) {
  // log(exp(d) exp(xi)) = xi + J_l^-1 d;  log(exp(xi) exp(d)) = xi + J_r^-1 d.
  for (const Vec6& xi : se3JacobianTwists()) {
    const SE3 T = SE3::exp(xi);
    const Mat6 Jl_inv = test::numericJacobianOnManifold<6>(
        [](const SE3& X) { return X.log(); }, T,
        [](const SE3& X, const Vec6& d) { return SE3::exp(d) * X; }, 1e-7);
    const Mat6 Jr_inv = test::numericJacobianOnManifold<6>(
        [](const SE3& X) { return X.log(); }, T,
        [](const SE3& X, const Vec6& d) { return X * SE3::exp(d); }, 1e-7);
    const double scale = std::max(1.0, maxAbs(se3LeftJacobianInverse(xi)));
    EXPECT_LT(maxAbs(se3LeftJacobianInverse(xi) - Jl_inv) / scale, 2e-6) << xi.transpose();
    EXPECT_LT(maxAbs(se3RightJacobianInverse(xi) - Jr_inv) / scale, 2e-6) << xi.transpose();
    EXPECT_LT(maxAbs(se3LeftJacobian(xi) * se3LeftJacobianInverse(xi) - Mat6::Identity()),
              1e-11 * scale);
    EXPECT_LT(maxAbs(se3RightJacobian(xi) * se3RightJacobianInverse(xi) - Mat6::Identity()),
              1e-11 * scale);
  }
}

TEST(Se3Jacobian, PointActionUnderRightPerturbation) {
  // d(T exp(d) p)/dd = R [-p^  I] with twists [phi; rho]: checks the manifold helper itself.
  const SE3 T(so3ExpQuat(Vec3(0.3, -0.2, 1.1)), Vec3(0.5, 0.1, -2.0));
  const Vec3 p(1.0, -2.0, 3.0);
  Mat36 expected;
  expected << -T.rotationMatrix() * hat(p), T.rotationMatrix();
  const Mat36 J = test::numericJacobianOnManifold<6>(
      [&](const SE3& X) { return X * p; }, T,
      [](const SE3& X, const Vec6& d) { return X * SE3::exp(d); });
  EXPECT_LT(maxAbs(expected - J), 1e-8);
}

// ---- Sim3 -----------------------------------------------------------------------------------

TEST(Sim3, ComposeAndInverseMatchMatrices) {
  const Sim3 S_a_b(so3ExpQuat(Vec3(0.2, -0.5, 0.9)), Vec3(1.0, -2.0, 0.5), 1.7);
  const Sim3 S_b_c(so3ExpQuat(Vec3(-1.0, 0.3, 0.1)), Vec3(0.2, 0.4, -1.0), 0.6);
  const Vec3 p_c(0.3, 1.5, -0.8);
  EXPECT_LT(((S_a_b * S_b_c).matrix() - S_a_b.matrix() * S_b_c.matrix()).norm(), 1e-14);
  EXPECT_NEAR((S_a_b * S_b_c).scale(), 1.7 * 0.6, 1e-15);
  EXPECT_LT(((S_a_b * S_b_c) * p_c - S_a_b * (S_b_c * p_c)).norm(), 1e-14);
  EXPECT_LT((S_a_b.inverse().matrix() - S_a_b.matrix().inverse()).norm(), 1e-14);
  const Sim3 identity = S_a_b.inverse() * S_a_b;
  EXPECT_NEAR(identity.scale(), 1.0, 1e-15);
  EXPECT_LT(identity.translation().norm(), 1e-15);
  EXPECT_LT((identity.rotationMatrix() - Mat3::Identity()).norm(), 1e-15);
  const Vec3 p_a = S_a_b * p_c;
  EXPECT_LT((p_a - (1.7 * S_a_b.rotationMatrix() * p_c + S_a_b.translation())).norm(), 1e-14);
}

TEST(Sim3, TransformPoseMapsCameraCentreAndRotation) {
  const Sim3 S(so3ExpQuat(Vec3(0.1, 0.2, 0.3)), Vec3(1.0, 0.0, -1.0), 2.0);
  const SE3 T_w_c(so3ExpQuat(Vec3(-0.5, 0.4, 0.0)), Vec3(0.5, 1.5, 2.0));
  const SE3 mapped = S.transformPose(T_w_c);
  EXPECT_LT((mapped.translation() - S * T_w_c.translation()).norm(), 1e-14);
  EXPECT_LT((mapped.rotationMatrix() - S.rotationMatrix() * T_w_c.rotationMatrix()).norm(), 1e-14);
  // A Sim3 built from an SE3 acts as that SE3.
  const Vec3 p(0.3, -0.2, 4.0);
  EXPECT_LT((Sim3(T_w_c) * p - T_w_c * p).norm(), 1e-14);
}

}  // namespace
}  // namespace ltlo
