// Graph edges (factors): a fixed-size residual over one or more vertices, with information
// matrix, optional robust kernel, analytic Jacobians or an automatic central-difference fallback.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include "sparse_opt/robust_kernel.h"
#include "sparse_opt/vertex.h"

namespace sparse_opt {

/// Misuse of the library (unknown vertex, dimension mismatch, non-finite residual...).
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Type-erased edge as seen by the graph and the solver. Owned by a Graph once added.
class EdgeBase {
 public:
  virtual ~EdgeBase() = default;
  EdgeBase(const EdgeBase&) = delete;
  EdgeBase& operator=(const EdgeBase&) = delete;

  /// Id assigned by Graph::addEdge (-1 before).
  int id() const { return id_; }
  /// Residual dimension.
  virtual int dimension() const = 0;
  int numVertices() const { return static_cast<int>(vertices_.size()); }
  VertexBase* vertex(int i) const { return vertices_.at(static_cast<size_t>(i)); }
  /// Attaches vertex slot i; throws Error if the vertex type does not match the edge's template.
  void setVertex(int i, VertexBase* v);

  /// Only edges whose level equals Options::level take part in an optimisation.
  int level() const { return level_; }
  void setLevel(int level) { level_ = level; }

  void setRobustKernel(std::unique_ptr<RobustKernel> kernel) { kernel_ = std::move(kernel); }
  const RobustKernel* robustKernel() const { return kernel_.get(); }
  RobustKernel* robustKernel() { return kernel_.get(); }

  /// Per-edge weight w >= 0 on the cost: the edge contributes w rho(e^T Omega e) (w e^T Omega e
  /// without kernel), so gradient and Hessian are scaled by w while the kernel still acts on the
  /// unweighted s = e^T Omega e (Ceres' ScaledLoss). w = 0 leaves the edge in the system with no
  /// weight: move it to another level instead when it must not count (a vertex seen only by such
  /// edges would be singular). Default 1.
  void setCostScale(double scale);
  double costScale() const { return cost_scale_; }

  /// e^T Omega e (without robust kernel or cost scale) at the last evaluation; after
  /// Graph::optimize it is the value at the final estimate, also for edges of other levels.
  double chi2() const { return chi2_; }
  /// costScale() * rho(chi2) with the robust kernel (costScale() * chi2 if none).
  double robustChi2() const;

  /// Fills the residual from the current vertex estimates (read them through estimate<I>()).
  virtual void computeError() = 0;
  /// Fills the Jacobians d error / d delta_i at the estimates of the last computeError(), which
  /// the solver (and linearize()) always calls first: an edge may reuse what computeError() left.
  /// The default is numeric (central differences).
  virtual void linearizeOplus() = 0;

  std::string typeName() const;

  // ---- Solver interface (called by Graph; not meant for users) ----
  /// computeError() and chi2(); returns rho(chi2).
  double evaluateChi2();
  /// computeError(), linearizeOplus() and the robust weights. Returns false if non-finite.
  bool linearize() {
    computeError();
    return linearizeAtError();
  }
  /// linearizeOplus() and the robust weights at the residual computeError() last left: the solver
  /// linearises right after evaluateChi2() at the same estimates, so it skips the second
  /// computeError() (about a third of a reprojection edge's linearisation). Returns false if
  /// non-finite.
  virtual bool linearizeAtError() = 0;
  /// true if the error is finite.
  virtual bool errorFinite() const = 0;
  /// out (dim(a) x dim(b), column-major) += J_a^T W J_b.
  virtual void addHessianBlock(int a, int b, double* out) const = 0;
  /// out (dim(a)) -= J_a^T W e.
  virtual void addGradient(int a, double* out) const = 0;
  /// Error and Jacobians as text for an error message.
  virtual std::string describeValues() const = 0;

 protected:
  explicit EdgeBase(int num_vertices) : vertices_(static_cast<size_t>(num_vertices), nullptr) {}
  virtual bool acceptsVertex(int i, const VertexBase* v) const = 0;
  virtual double squaredError() const = 0;

  std::vector<VertexBase*> vertices_;
  double robust_weight_ = 1.0;  // cost_scale_ * rho'(chi2) at the last linearisation
  double cost_scale_ = 1.0;

 private:
  friend class Graph;
  int id_ = -1;
  int level_ = 0;
  double chi2_ = 0.0;
  std::unique_ptr<RobustKernel> kernel_;
};

namespace detail {
template <int N, typename F>
void dispatchIndex(int i, F&& f) {
  if constexpr (N > 0) {
    if (i == N - 1) {
      f(std::integral_constant<int, N - 1>{});
    } else {
      dispatchIndex<N - 1>(i, std::forward<F>(f));
    }
  }
}
template <typename F, int... I>
void forEachIndex(F&& f, std::integer_sequence<int, I...>) {
  (f(std::integral_constant<int, I>{}), ...);
}
}  // namespace detail

/// Edge with residual dimension D, measurement type E and vertex types VertexTypes... (each a
/// BaseVertex). Derived classes implement computeError() (reading estimates with estimate<I>())
/// and may override linearizeOplus() filling jacobian<I>(); otherwise central differences are used.
template <int D, typename E, typename... VertexTypes>
class BaseEdge : public EdgeBase {
 public:
  static constexpr int kDimension = D;
  static constexpr int kNumVertices = static_cast<int>(sizeof...(VertexTypes));
  using Measurement = E;
  using ErrorVector = Eigen::Matrix<double, D, 1>;
  using InformationMatrix = Eigen::Matrix<double, D, D>;
  template <int I>
  using VertexType = std::tuple_element_t<static_cast<size_t>(I), std::tuple<VertexTypes...>>;
  template <int I>
  using JacobianType = Eigen::Matrix<double, D, VertexType<I>::kDimension>;

  // Jacobians start at zero: an analytic linearizeOplus() may skip a fixed vertex's block, which
  // the solver never reads.
  BaseEdge() : EdgeBase(kNumVertices), information_(InformationMatrix::Identity()), error_(ErrorVector::Zero()) {
    detail::forEachIndex([this](auto i) { std::get<decltype(i)::value>(jacobians_).setZero(); },
                         std::make_integer_sequence<int, kNumVertices>{});
  }

  int dimension() const final { return D; }

  const E& measurement() const { return measurement_; }
  void setMeasurement(const E& m) { measurement_ = m; }
  const InformationMatrix& information() const { return information_; }
  void setInformation(const InformationMatrix& info) { information_ = info; }
  const ErrorVector& error() const { return error_; }

  template <int I>
  const VertexType<I>* vertexAs() const {
    return static_cast<const VertexType<I>*>(vertices_[I]);
  }
  /// Estimate of vertex I as seen by computeError() (a perturbed copy during numeric differences).
  template <int I>
  const typename VertexType<I>::EstimateType& estimate() const {
    const auto* override_estimate = std::get<I>(overrides_);
    return override_estimate != nullptr ? *override_estimate : vertexAs<I>()->estimate();
  }
  template <int I>
  JacobianType<I>& jacobian() {
    return std::get<I>(jacobians_);
  }
  template <int I>
  const JacobianType<I>& jacobian() const {
    return std::get<I>(jacobians_);
  }

  void linearizeOplus() override { numericJacobians(); }

  /// Central differences with step 1e-6 for every non-fixed vertex. Thread-safe: it perturbs
  /// private copies of the estimates, never the vertices.
  void numericJacobians() {
    const ErrorVector error0 = error_;
    detail::forEachIndex([this](auto i) { numericJacobian<decltype(i)::value>(); },
                         std::make_integer_sequence<int, kNumVertices>{});
    error_ = error0;
  }

  // ---- Solver interface ----
  bool linearizeAtError() final {
    const double s = squaredError();
    robust_weight_ = cost_scale_;
    if (robustKernel() != nullptr) robust_weight_ *= robustKernel()->evaluate(s)[1];
    if (!error_.allFinite()) return false;
    linearizeOplus();
    bool finite = true;
    detail::forEachIndex(
        [&](auto i) {
          if (!vertices_[decltype(i)::value]->fixed() && !std::get<decltype(i)::value>(jacobians_).allFinite())
            finite = false;
        },
        std::make_integer_sequence<int, kNumVertices>{});
    weighted_information_ = robust_weight_ * information_;
    weighted_error_ = weighted_information_ * error_;
    return finite;
  }
  bool errorFinite() const final { return error_.allFinite(); }

  void addHessianBlock(int a, int b, double* out) const final {
    detail::dispatchIndex<kNumVertices>(a, [&](auto ia) {
      constexpr int A = decltype(ia)::value;
      const Eigen::Matrix<double, VertexType<A>::kDimension, D> jt_w =
          std::get<A>(jacobians_).transpose() * weighted_information_;
      detail::dispatchIndex<kNumVertices>(b, [&](auto ib) {
        constexpr int B = decltype(ib)::value;
        Eigen::Map<Eigen::Matrix<double, VertexType<A>::kDimension, VertexType<B>::kDimension>> block(out);
        block.noalias() += jt_w * std::get<B>(jacobians_);
      });
    });
  }
  void addGradient(int a, double* out) const final {
    detail::dispatchIndex<kNumVertices>(a, [&](auto ia) {
      constexpr int A = decltype(ia)::value;
      Eigen::Map<Eigen::Matrix<double, VertexType<A>::kDimension, 1>> g(out);
      g.noalias() -= std::get<A>(jacobians_).transpose() * weighted_error_;
    });
  }
  std::string describeValues() const final {
    std::string text = "residual [";
    for (int r = 0; r < D; ++r) text += (r ? ", " : "") + std::to_string(error_[r]);
    text += "]";
    detail::forEachIndex(
        [&](auto i) {
          if (!std::get<decltype(i)::value>(jacobians_).allFinite())
            text += ", jacobian " + std::to_string(decltype(i)::value) + " not finite";
        },
        std::make_integer_sequence<int, kNumVertices>{});
    return text;
  }

 protected:
  bool acceptsVertex(int i, const VertexBase* v) const final {
    bool ok = false;
    detail::dispatchIndex<kNumVertices>(
        i, [&](auto ii) { ok = dynamic_cast<const VertexType<decltype(ii)::value>*>(v) != nullptr; });
    return ok;
  }
  double squaredError() const final { return error_.dot(information_ * error_); }

  E measurement_{};
  InformationMatrix information_;
  ErrorVector error_;

 private:
  template <int I>
  void numericJacobian() {
    using V = VertexType<I>;
    constexpr double kStep = 1e-6;
    JacobianType<I>& jac = std::get<I>(jacobians_);
    if (vertices_[I]->fixed()) {
      jac.setZero();
      return;
    }
    const V* v = vertexAs<I>();
    const typename V::EstimateType x0 = v->estimate();
    typename V::Delta delta = V::Delta::Zero();
    for (int k = 0; k < V::kDimension; ++k) {
      delta[k] = kStep;
      const typename V::EstimateType x_plus = v->plus(x0, delta);
      std::get<I>(overrides_) = &x_plus;
      computeError();
      const ErrorVector e_plus = error_;
      delta[k] = -kStep;
      const typename V::EstimateType x_minus = v->plus(x0, delta);
      std::get<I>(overrides_) = &x_minus;
      computeError();
      jac.col(k) = (e_plus - error_) / (2.0 * kStep);
      delta[k] = 0.0;
      std::get<I>(overrides_) = nullptr;
    }
  }

  std::tuple<Eigen::Matrix<double, D, VertexTypes::kDimension>...> jacobians_;
  std::tuple<const typename VertexTypes::EstimateType*...> overrides_{};
  InformationMatrix weighted_information_ = InformationMatrix::Zero();
  ErrorVector weighted_error_ = ErrorVector::Zero();
};

}  // namespace sparse_opt
