// Graph vertices: a fixed-size estimate living on a manifold with a local update ("oplus").
#pragma once

#include <Eigen/Core>
#include <string>

namespace sparse_opt {

class Graph;

/// Type-erased vertex as seen by the graph and the solver. Not thread-safe; owned by a Graph.
class VertexBase {
 public:
  explicit VertexBase(int id) : id_(id) {}
  virtual ~VertexBase() = default;
  VertexBase(const VertexBase&) = delete;
  VertexBase& operator=(const VertexBase&) = delete;

  int id() const { return id_; }
  /// Dimension of the local (tangent) update.
  virtual int dimension() const = 0;

  /// Fixed vertices are never updated by the optimiser (their estimate stays bit-exact).
  bool fixed() const { return fixed_; }
  void setFixed(bool fixed) { fixed_ = fixed; }
  /// Marginalised vertices (landmarks) are eliminated by the Schur complement.
  bool marginalized() const { return marginalized_; }
  void setMarginalized(bool marginalized) { marginalized_ = marginalized; }

  /// estimate <- plus(estimate, delta); delta has dimension() entries.
  virtual void oplus(const double* delta) = 0;
  /// One-slot backup used by the optimiser to undo a rejected step.
  virtual void saveForRollback() = 0;
  virtual void rollback() = 0;

  /// Readable type name for error messages.
  std::string typeName() const;

 private:
  int id_;
  bool fixed_ = false;
  bool marginalized_ = false;
};

/// Vertex with tangent dimension D and estimate type T. Derived classes implement plus().
template <int D, typename T>
class BaseVertex : public VertexBase {
 public:
  static constexpr int kDimension = D;
  using EstimateType = T;
  using Delta = Eigen::Matrix<double, D, 1>;

  explicit BaseVertex(int id, const T& estimate = T()) : VertexBase(id), estimate_(estimate), backup_(estimate) {}

  int dimension() const final { return D; }
  const T& estimate() const { return estimate_; }
  void setEstimate(const T& estimate) { estimate_ = estimate; }

  /// The manifold update x [+] delta. Must be const and side-effect free (numeric Jacobians call
  /// it on copies from two threads).
  virtual T plus(const T& x, const Delta& delta) const = 0;

  void oplus(const double* delta) final { estimate_ = plus(estimate_, Eigen::Map<const Delta>(delta)); }
  void saveForRollback() final { backup_ = estimate_; }
  void rollback() final { estimate_ = backup_; }

 private:
  T estimate_;
  T backup_;
};

}  // namespace sparse_opt
