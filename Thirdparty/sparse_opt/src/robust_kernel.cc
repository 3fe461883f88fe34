#include "sparse_opt/robust_kernel.h"

#include <cmath>

namespace sparse_opt {

Eigen::Vector3d HuberKernel::evaluate(double s) const {
  const double delta2 = delta_ * delta_;
  if (s <= delta2) return {s, 1.0, 0.0};
  const double sqrt_s = std::sqrt(s);
  return {2.0 * delta_ * sqrt_s - delta2, delta_ / sqrt_s, -0.5 * delta_ / (s * sqrt_s)};
}

Eigen::Vector3d CauchyKernel::evaluate(double s) const {
  const double delta2 = delta_ * delta_;
  const double inv = 1.0 / (1.0 + s / delta2);
  return {delta2 * std::log1p(s / delta2), inv, -inv * inv / delta2};
}

Eigen::Vector3d TukeyKernel::evaluate(double s) const {
  const double delta2 = delta_ * delta_;
  if (s > delta2) return {delta2 / 3.0, 0.0, 0.0};
  const double a = 1.0 - s / delta2;
  return {delta2 / 3.0 * (1.0 - a * a * a), a * a, -2.0 * a / delta2};
}

}  // namespace sparse_opt
