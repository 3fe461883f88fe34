#include "ltlo/core/camera_model.h"

#include <cmath>
#include <sstream>

#include "ltlo/core/assert.h"

namespace ltlo {

const char* lensModelName(LensModel model) {
  switch (model) {
    case LensModel::kPinhole: return "pinhole";
    case LensModel::kRadTan: return "radtan";
    case LensModel::kRational: return "rational";
    case LensModel::kKannalaBrandt: return "kannala-brandt";
  }
  return "unknown";
}

bool LensDistortion::isDistorted() const {
  if (model == LensModel::kPinhole) return false;
  return k1 != 0.0 || k2 != 0.0 || k3 != 0.0 || k4 != 0.0 || k5 != 0.0 || k6 != 0.0 || p1 != 0.0 || p2 != 0.0;
}

namespace {

// Radial factor of the radtan/rational models as a function of r^2, and its derivative in r^2.
struct RadialFactor {
  double value;
  double d_r2;
};

RadialFactor rationalRadial(const LensDistortion& lens, double r2) {
  const double num = 1.0 + r2 * (lens.k1 + r2 * (lens.k2 + r2 * lens.k3));
  const double d_num = lens.k1 + r2 * (2.0 * lens.k2 + 3.0 * r2 * lens.k3);
  if (lens.model != LensModel::kRational) return {num, d_num};
  const double den = 1.0 + r2 * (lens.k4 + r2 * (lens.k5 + r2 * lens.k6));
  const double d_den = lens.k4 + r2 * (2.0 * lens.k5 + 3.0 * r2 * lens.k6);
  return {num / den, (d_num * den - num * d_den) / (den * den)};
}

// Kannala-Brandt: x_d = s(r) x_n with s = theta_d(theta(r)) / r, and ds/dr.
struct EquidistantScale {
  double s;
  double d_r;
};

EquidistantScale equidistantScale(const LensDistortion& lens, double r) {
  if (r < 1e-9) return {1.0, 0.0};  // s -> 1, ds/dr -> 0 at the optical axis
  const double theta = std::atan(r);
  const double t2 = theta * theta;
  const double poly = 1.0 + t2 * (lens.k1 + t2 * (lens.k2 + t2 * (lens.k3 + t2 * lens.k4)));
  const double d_poly = 1.0 + t2 * (3.0 * lens.k1 + t2 * (5.0 * lens.k2 + t2 * (7.0 * lens.k3 + t2 * 9.0 * lens.k4)));
  const double theta_d = theta * poly;
  const double d_theta_d_d_r = d_poly / (1.0 + r * r);  // d theta_d / d theta * d theta / d r
  return {theta_d / r, (d_theta_d_d_r * r - theta_d) / (r * r)};
}

}  // namespace

Vec2 LensDistortion::distort(const Vec2& x_n) const {
  const double x = x_n.x(), y = x_n.y();
  switch (model) {
    case LensModel::kPinhole: return x_n;
    case LensModel::kRadTan:
    case LensModel::kRational: {
      const double r2 = x * x + y * y;
      const double radial = rationalRadial(*this, r2).value;
      return Vec2(x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                  y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y);
    }
    case LensModel::kKannalaBrandt: return equidistantScale(*this, x_n.norm()).s * x_n;
  }
  return x_n;
}

Mat2 LensDistortion::distortJacobian(const Vec2& x_n) const {
  const double x = x_n.x(), y = x_n.y();
  Mat2 J = Mat2::Identity();
  switch (model) {
    case LensModel::kPinhole: break;
    case LensModel::kRadTan:
    case LensModel::kRational: {
      const double r2 = x * x + y * y;
      const RadialFactor radial = rationalRadial(*this, r2);
      J(0, 0) = radial.value + 2.0 * x * x * radial.d_r2 + 2.0 * p1 * y + 6.0 * p2 * x;
      J(0, 1) = 2.0 * x * y * radial.d_r2 + 2.0 * p1 * x + 2.0 * p2 * y;
      J(1, 0) = 2.0 * x * y * radial.d_r2 + 2.0 * p1 * x + 2.0 * p2 * y;
      J(1, 1) = radial.value + 2.0 * y * y * radial.d_r2 + 6.0 * p1 * y + 2.0 * p2 * x;
      break;
    }
    case LensModel::kKannalaBrandt: {
      const double r = x_n.norm();
      const EquidistantScale scale = equidistantScale(*this, r);
      J = scale.s * Mat2::Identity();
      if (r >= 1e-9) J += (scale.d_r / r) * x_n * x_n.transpose();
      break;
    }
  }
  return J;
}

std::optional<Vec2> LensDistortion::undistort(const Vec2& x_d) const {
  if (!isDistorted()) return x_d;
  Vec2 x = x_d;
  for (int iteration = 0; iteration < 50; ++iteration) {
    const Vec2 residual = distort(x) - x_d;
    if (!residual.allFinite()) return std::nullopt;
    if (residual.squaredNorm() < 1e-24) {
      // A fold of the lens model (Jacobian not positive) is outside its valid field.
      if (distortJacobian(x).determinant() <= 0.0) return std::nullopt;
      return x;
    }
    const Mat2 J = distortJacobian(x);
    const double det = J.determinant();
    if (!(det > 1e-12)) return std::nullopt;
    x -= J.inverse() * residual;
  }
  return std::nullopt;
}

std::string LensDistortion::describe() const {
  std::ostringstream text;
  text << lensModelName(model);
  switch (model) {
    case LensModel::kPinhole: break;
    case LensModel::kRadTan:
      text << " k1=" << k1 << " k2=" << k2 << " p1=" << p1 << " p2=" << p2 << " k3=" << k3;
      break;
    case LensModel::kRational:
      text << " k1=" << k1 << " k2=" << k2 << " p1=" << p1 << " p2=" << p2 << " k3=" << k3 << " k4=" << k4
           << " k5=" << k5 << " k6=" << k6;
      break;
    case LensModel::kKannalaBrandt:
      text << " k1=" << k1 << " k2=" << k2 << " k3=" << k3 << " k4=" << k4;
      break;
  }
  return text.str();
}

Vec2 CameraModel::project(const Vec3& p_c) const {
  const double inv_z = 1.0 / p_c.z();
  const Vec2 x_d = lens_.distort(Vec2(p_c.x() * inv_z, p_c.y() * inv_z));
  return Vec2(pinhole_.fx() * x_d.x() + pinhole_.cx(), pinhole_.fy() * x_d.y() + pinhole_.cy());
}

Mat23 CameraModel::projectJacobian(const Vec3& p_c) const {
  const double inv_z = 1.0 / p_c.z();
  const Vec2 x_n(p_c.x() * inv_z, p_c.y() * inv_z);
  Mat23 d_xn_d_p;
  d_xn_d_p << inv_z, 0.0, -x_n.x() * inv_z,  //
      0.0, inv_z, -x_n.y() * inv_z;
  const Mat2 F = Eigen::Vector2d(pinhole_.fx(), pinhole_.fy()).asDiagonal();
  return F * lens_.distortJacobian(x_n) * d_xn_d_p;
}

std::optional<Vec3> CameraModel::unproject(const Vec2& u_raw) const {
  const Vec2 x_d((u_raw.x() - pinhole_.cx()) / pinhole_.fx(), (u_raw.y() - pinhole_.cy()) / pinhole_.fy());
  const std::optional<Vec2> x_n = lens_.undistort(x_d);
  if (!x_n) return std::nullopt;
  return Vec3(x_n->x(), x_n->y(), 1.0);
}

Eigen::Matrix<double, 3, 2> CameraModel::unprojectJacobian(const Vec2& u_raw) const {
  const std::optional<Vec3> ray = unproject(u_raw);
  LTLO_ASSERT(ray.has_value(), "unprojectJacobian at (" << u_raw.x() << ", " << u_raw.y() << "): outside the lens' field");
  // Inverse function theorem: d x_n / d x_d = (d x_d / d x_n)^-1 at the solution.
  const Mat2 d_xn_d_xd = lens_.distortJacobian(ray->head<2>()).inverse();
  const Mat2 d_xd_d_u = Eigen::Vector2d(1.0 / pinhole_.fx(), 1.0 / pinhole_.fy()).asDiagonal();
  Eigen::Matrix<double, 3, 2> J = Eigen::Matrix<double, 3, 2>::Zero();
  J.topRows<2>() = d_xn_d_xd * d_xd_d_u;
  return J;
}

std::optional<Vec2> CameraModel::undistortPixel(const Vec2& u_raw) const {
  const std::optional<Vec3> ray = unproject(u_raw);
  if (!ray) return std::nullopt;
  return Vec2(pinhole_.fx() * ray->x() + pinhole_.cx(), pinhole_.fy() * ray->y() + pinhole_.cy());
}

Vec2 CameraModel::distortPixel(const Vec2& u_ideal) const {
  return project(Vec3((u_ideal.x() - pinhole_.cx()) / pinhole_.fx(), (u_ideal.y() - pinhole_.cy()) / pinhole_.fy(), 1.0));
}

}  // namespace ltlo
