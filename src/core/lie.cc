#include "ltlo/core/lie.h"

#include <cmath>

namespace ltlo {
namespace {

// Below this angle the closed forms lose digits to cancellation; Taylor series take over.
constexpr double kSmallAngle = 1e-2;

// (theta - sin theta) / theta^3
double coeffThetaMinusSin(double theta) {
  const double t2 = theta * theta;
  if (theta < kSmallAngle) return 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0;
  return (theta - std::sin(theta)) / (t2 * theta);
}

// (1 - cos theta) / theta^2
double coeffOneMinusCos(double theta) {
  const double t2 = theta * theta;
  if (theta < kSmallAngle) return 0.5 - t2 / 24.0 + t2 * t2 / 720.0;
  return (1.0 - std::cos(theta)) / t2;
}

// Q(rho, phi) of the SE(3) left Jacobian (Barfoot, "State Estimation for Robotics", Eq. 7.86).
Mat3 se3LeftJacobianQ(const Vec3& phi, const Vec3& rho) {
  const double theta = phi.norm();
  const double t2 = theta * theta;
  double c1, c2, c3;
  if (theta < kSmallAngle) {
    c1 = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0;
    c2 = 1.0 / 24.0 - t2 / 720.0 + t2 * t2 / 40320.0;
    c3 = 1.0 / 120.0 - t2 / 2520.0 + t2 * t2 / 120960.0;
  } else {
    const double s = std::sin(theta), c = std::cos(theta);
    c1 = (theta - s) / (t2 * theta);
    c2 = (t2 + 2.0 * c - 2.0) / (2.0 * t2 * t2);
    c3 = (2.0 * theta - 3.0 * s + theta * c) / (2.0 * t2 * t2 * theta);
  }
  const Mat3 P = hat(phi);
  const Mat3 Rh = hat(rho);
  const Mat3 PR = P * Rh;
  const Mat3 RP = Rh * P;
  const Mat3 PRP = PR * P;
  return 0.5 * Rh + c1 * (PR + RP + PRP) + c2 * (P * PR + RP * P - 3.0 * PRP) +
         c3 * (PRP * P + P * PRP);
}

}  // namespace

Mat3 hat(const Vec3& v) {
  Mat3 m;
  m << 0.0, -v.z(), v.y(),  //
      v.z(), 0.0, -v.x(),   //
      -v.y(), v.x(), 0.0;
  return m;
}

Vec3 vee(const Mat3& m) {
  return 0.5 * Vec3(m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1));
}

Quat so3ExpQuat(const Vec3& phi) {
  const double theta = phi.norm();
  double w, k;  // q = [cos(theta/2), k * phi] with k = sin(theta/2) / theta
  if (theta < kSmallAngle) {
    const double t2 = theta * theta;
    w = 1.0 - t2 / 8.0 + t2 * t2 / 384.0;
    k = 0.5 - t2 / 48.0 + t2 * t2 / 3840.0;
  } else {
    w = std::cos(0.5 * theta);
    k = std::sin(0.5 * theta) / theta;
  }
  Quat q(w, k * phi.x(), k * phi.y(), k * phi.z());
  return normalizeQuat(q);
}

Mat3 so3Exp(const Vec3& phi) { return so3ExpQuat(phi).toRotationMatrix(); }

Vec3 so3Log(const Quat& q_in) {
  const Quat q = normalizeQuat(q_in);
  const Vec3 v = q.vec();
  const double sin_half = v.norm();
  const double w = q.w();
  // theta = 2 atan2(|v|, w); phi = theta * v / |v|. atan2 keeps full precision near pi (w -> 0).
  if (sin_half < 1e-8) {
    // 2 atan(x)/x ~= 2 (1 - x^2/3) with x = |v| / w, w ~= 1 here.
    const double x2 = (sin_half * sin_half) / (w * w);
    return (2.0 / w) * (1.0 - x2 / 3.0) * v;
  }
  const double theta = 2.0 * std::atan2(sin_half, w);
  return (theta / sin_half) * v;
}

Vec3 so3Log(const Mat3& R) { return so3Log(Quat(R)); }

Mat3 so3RightJacobian(const Vec3& phi) {
  const double theta = phi.norm();
  const Mat3 P = hat(phi);
  return Mat3::Identity() - coeffOneMinusCos(theta) * P + coeffThetaMinusSin(theta) * P * P;
}

Mat3 so3RightJacobianInverse(const Vec3& phi) {
  const double theta = phi.norm();
  const Mat3 P = hat(phi);
  double c;  // 1/theta^2 - (1 + cos theta) / (2 theta sin theta) = 1/theta^2 - cot(theta/2) / (2 theta)
  if (theta < kSmallAngle) {
    const double t2 = theta * theta;
    c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0;
  } else {
    c = 1.0 / (theta * theta) - 1.0 / (2.0 * theta * std::tan(0.5 * theta));
  }
  return Mat3::Identity() + 0.5 * P + c * P * P;
}

Mat3 so3LeftJacobian(const Vec3& phi) { return so3RightJacobian(-phi); }
Mat3 so3LeftJacobianInverse(const Vec3& phi) { return so3RightJacobianInverse(-phi); }

Quat normalizeQuat(const Quat& q) {
  Quat n = q.normalized();
  if (n.w() < 0.0) n.coeffs() = -n.coeffs();
  return n;
}

Mat3 normalizeRotation(const Mat3& R) {
  // Eigen's matrix->quaternion conversion only reads the rotation part robustly when R is close to
  // orthonormal; an SVD projection handles larger drift.
  Eigen::JacobiSVD<Mat3> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 U = svd.matrixU();
  const Mat3 V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0.0) U.col(2) = -U.col(2);
  return U * V.transpose();
}

// ---- SE3 ----------------------------------------------------------------------------------------

SE3 SE3::fromMatrix(const Mat4& T) {
  return SE3(Mat3(T.block<3, 3>(0, 0)), Vec3(T.block<3, 1>(0, 3)));
}

SE3 SE3::exp(const Vec6& xi) {
  const Vec3 phi = xi.head<3>();
  const Vec3 rho = xi.tail<3>();
  return SE3(so3ExpQuat(phi), Vec3(so3LeftJacobian(phi) * rho));
}

Vec6 SE3::log() const {
  const Vec3 phi = so3Log(q_);
  Vec6 xi;
  xi.head<3>() = phi;
  xi.tail<3>() = so3LeftJacobianInverse(phi) * t_;
  return xi;
}

Mat4 SE3::matrix() const {
  Mat4 T = Mat4::Identity();
  T.block<3, 3>(0, 0) = rotationMatrix();
  T.block<3, 1>(0, 3) = t_;
  return T;
}

Eigen::Matrix<double, 3, 4> SE3::matrix3x4() const {
  Eigen::Matrix<double, 3, 4> T;
  T.block<3, 3>(0, 0) = rotationMatrix();
  T.col(3) = t_;
  return T;
}

SE3 SE3::inverse() const {
  const Quat q_inv = q_.conjugate();
  return SE3(q_inv, -(q_inv * t_));
}

Mat6 SE3::adjoint() const {
  const Mat3 R = rotationMatrix();
  Mat6 ad = Mat6::Zero();
  ad.block<3, 3>(0, 0) = R;
  ad.block<3, 3>(3, 0) = hat(t_) * R;
  ad.block<3, 3>(3, 3) = R;
  return ad;
}

Mat6 se3LeftJacobian(const Vec6& xi) {
  const Vec3 phi = xi.head<3>();
  const Mat3 Jl = so3LeftJacobian(phi);
  Mat6 J = Mat6::Zero();
  J.block<3, 3>(0, 0) = Jl;
  J.block<3, 3>(3, 0) = se3LeftJacobianQ(phi, xi.tail<3>());
  J.block<3, 3>(3, 3) = Jl;
  return J;
}

Mat6 se3LeftJacobianInverse(const Vec6& xi) {
  const Vec3 phi = xi.head<3>();
  const Mat3 Jl_inv = so3LeftJacobianInverse(phi);
  Mat6 J = Mat6::Zero();
  J.block<3, 3>(0, 0) = Jl_inv;
  J.block<3, 3>(3, 0) = -Jl_inv * se3LeftJacobianQ(phi, xi.tail<3>()) * Jl_inv;
  J.block<3, 3>(3, 3) = Jl_inv;
  return J;
}

Mat6 se3RightJacobian(const Vec6& xi) { return se3LeftJacobian(-xi); }
Mat6 se3RightJacobianInverse(const Vec6& xi) { return se3LeftJacobianInverse(-xi); }

// ---- Sim3 ---------------------------------------------------------------------------------------

Mat4 Sim3::matrix() const {
  Mat4 T = Mat4::Identity();
  T.block<3, 3>(0, 0) = scale_ * rotationMatrix();
  T.block<3, 1>(0, 3) = t_;
  return T;
}

Sim3 Sim3::inverse() const {
  const Quat q_inv = q_.conjugate();
  const double s_inv = 1.0 / scale_;
  return Sim3(q_inv, -s_inv * (q_inv * t_), s_inv);
}

}  // namespace ltlo
