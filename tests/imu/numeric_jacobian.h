#pragma once
/// The imu tests differentiate with respect to a perturbation applied by the caller (f(delta), at
/// delta = 0); this adapts that form to the project's one numeric-Jacobian helper.
#include "common/numeric_jacobian.h"

namespace ltlo::imu::test {

/// J(:, k) = d f / d delta_k at delta = 0, f: R^N (perturbation) -> R^M.
template <int M, int N, typename Function>
Eigen::Matrix<double, M, N> numericJacobian(const Function& f, double eps = 1e-6) {
  return ::ltlo::test::numericJacobian(f, Eigen::Matrix<double, N, 1>::Zero(), eps);
}

}  // namespace ltlo::imu::test
