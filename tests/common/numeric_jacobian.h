#pragma once
/// Central-difference Jacobians: the one numeric-differentiation helper every test in the project
/// uses (STYLE.md section 9). Header-only, Eigen only; CMake target `ltlo_test_common`.
///
///   // f: R^n -> R^m on Eigen vectors (fixed or dynamic size)
///   const Mat23 J = test::numericJacobian([&](const Vec3& p_c) { return camera.project(p_c); },
///   p_c);
///
///   // manifold input: derivative with respect to a perturbation delta in R^n at delta = 0
///   const Mat36 J = test::numericJacobianOnManifold<6>(
///       [&](const SE3& T_c_w) { return camera.project(T_c_w * p_w); }, T_c_w,
///       [](const SE3& T, const Vec6& delta) { return T * SE3::exp(delta); });  // right
///       perturbation
///
/// A manifold-valued output is differentiated by returning a vector from f, e.g.
/// so3Log(R0.transpose() * g(x)) for a right-perturbed rotation output.
///
/// Lambdas that build Eigen products from temporaries must name their return type (`-> Vec3`):
/// an `auto` return would hand back a lazy view of a destroyed temporary (STYLE.md section 6).
///
/// Accuracy: the truncation error is O(eps^2 |f'''|) and the round-off O(1e-16 |f| / eps); the
/// default eps = 1e-6 gives ~1e-9 relative accuracy on smooth functions of order-one inputs.
#include <Eigen/Core>
#include <type_traits>
#include <utility>

namespace ltlo::test {

namespace detail {

// Output of f evaluated as a plain column vector (a scalar-valued f gives a 1-vector).
template <typename Out>
auto asColumn(const Out& value) {
  if constexpr (std::is_arithmetic_v<Out>) {
    return Eigen::Matrix<double, 1, 1>::Constant(static_cast<double>(value));
  } else {
    using Plain = Eigen::Matrix<double,
                                Out::RowsAtCompileTime == Eigen::Dynamic
                                    ? Eigen::Dynamic
                                    : Out::RowsAtCompileTime * Out::ColsAtCompileTime,
                                1>;
    const typename Out::PlainObject plain = value;
    return Plain(Eigen::Map<const Plain>(plain.data(), plain.size()));
  }
}

}  // namespace detail

/// Jacobian d f / d x at x by central differences, one column per coordinate of x.
/// f takes an Eigen column vector of x's size and returns an Eigen vector (or a scalar).
/// The result is m x n, fixed-size when both sizes are known at compile time.
template <typename F, typename Derived>
auto numericJacobian(const F& f, const Eigen::MatrixBase<Derived>& x_in, double eps = 1e-6) {
  static_assert(Derived::ColsAtCompileTime == 1, "numericJacobian: x must be a column vector");
  using X = Eigen::Matrix<double, Derived::RowsAtCompileTime, 1>;
  const X x = x_in;
  using Out = std::decay_t<decltype(f(std::declval<const X&>()))>;
  using Column = decltype(detail::asColumn(std::declval<const Out&>()));
  const Column y0 = detail::asColumn(f(x));
  Eigen::Matrix<double, Column::RowsAtCompileTime, X::RowsAtCompileTime> J(y0.size(), x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    X x_plus = x;
    X x_minus = x;
    x_plus(i) += eps;
    x_minus(i) -= eps;
    const Column y_plus = detail::asColumn(f(static_cast<const X&>(x_plus)));
    const Column y_minus = detail::asColumn(f(static_cast<const X&>(x_minus)));
    J.col(i) = (y_plus - y_minus) / (2.0 * eps);
  }
  return J;
}

/// Jacobian of f(plus(x, delta)) with respect to delta at delta = 0, for x on a manifold (SO3, SE3,
/// a state struct...). `plus(x, delta)` applies a kDim-vector perturbation, e.g. a right
/// perturbation T * SE3::exp(delta) or a left one SE3::exp(delta) * T; the convention chosen here
/// is the convention of the Jacobian being checked.
template <int kDim, typename F, typename X, typename Plus>
auto numericJacobianOnManifold(const F& f, const X& x, const Plus& plus, double eps = 1e-6) {
  using Delta = Eigen::Matrix<double, kDim, 1>;
  return numericJacobian(
      [&](const Delta& delta) {
        const X perturbed = plus(x, delta);     // a named value: f may return a view of it
        return detail::asColumn(f(perturbed));  // evaluated while `perturbed` lives
      },
      Delta::Zero().eval(), eps);
}

}  // namespace ltlo::test
