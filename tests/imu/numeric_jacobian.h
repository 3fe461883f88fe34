#pragma once
/// Central-difference Jacobian for tests (local to tests/imu until tests/common/numeric_jacobian.h
/// exists on this branch; then switch to the shared one).
#include <Eigen/Core>

namespace ltlo::imu::test {

/// J(:, k) = (f(eps e_k) - f(-eps e_k)) / (2 eps), where f maps an N-vector perturbation (applied
/// by the caller in the parametrisation under test) to an M-vector.
template <int M, int N, typename Function>
Eigen::Matrix<double, M, N> numericJacobian(const Function& f, double eps = 1e-6) {
  Eigen::Matrix<double, M, N> J;
  for (int k = 0; k < N; ++k) {
    Eigen::Matrix<double, N, 1> delta = Eigen::Matrix<double, N, 1>::Zero();
    delta[k] = eps;
    const Eigen::Matrix<double, M, 1> plus = f(delta);
    const Eigen::Matrix<double, M, 1> minus = f(Eigen::Matrix<double, N, 1>(-delta));
    J.col(k) = (plus - minus) / (2.0 * eps);
  }
  return J;
}

}  // namespace ltlo::imu::test
