// Robust kernels rho(s) applied to the squared Mahalanobis error s = e^T Omega e of one edge.
#pragma once

#include <Eigen/Core>

namespace sparse_opt {

/// rho(s), rho'(s), rho''(s) for s >= 0; delta is the per-edge threshold on the error norm.
class RobustKernel {
 public:
  explicit RobustKernel(double delta) : delta_(delta) {}
  virtual ~RobustKernel() = default;
  /// Returns [rho(s), rho'(s), rho''(s)].
  virtual Eigen::Vector3d evaluate(double s) const = 0;
  double delta() const { return delta_; }
  void setDelta(double delta) { delta_ = delta; }

 protected:
  double delta_;
};

/// Huber: s for s <= delta^2, 2 delta sqrt(s) - delta^2 beyond (same convention as Ceres' HuberLoss).
class HuberKernel final : public RobustKernel {
 public:
  using RobustKernel::RobustKernel;
  Eigen::Vector3d evaluate(double s) const override;
};

/// Cauchy: delta^2 log(1 + s / delta^2).
class CauchyKernel final : public RobustKernel {
 public:
  using RobustKernel::RobustKernel;
  Eigen::Vector3d evaluate(double s) const override;
};

/// Tukey biweight: delta^2/3 (1 - (1 - s/delta^2)^3) for s <= delta^2, delta^2/3 beyond.
class TukeyKernel final : public RobustKernel {
 public:
  using RobustKernel::RobustKernel;
  Eigen::Vector3d evaluate(double s) const override;
};

}  // namespace sparse_opt
