// Standard vertices and edges: SE3 pose, SO3 rotation, R^n vectors (3-D point, velocity, bias),
// pinhole reprojection, SE3 relative pose and SE3 prior.
#pragma once

#include "sparse_opt/edge.h"
#include "sparse_opt/manifold.h"
#include "sparse_opt/vertex.h"

namespace sparse_opt {

/// SE3 pose, updated by LEFT multiplication: T <- SE3::exp(delta) * T, delta = [phi; rho].
/// Used as T_c_w in bundle adjustment (world to camera) and as T_w_x in pose graphs.
class VertexSE3 final : public BaseVertex<6, SE3> {
 public:
  using BaseVertex::BaseVertex;
  SE3 plus(const SE3& x, const Delta& delta) const override { return SE3::exp(delta) * x; }
};

/// Rotation, updated by LEFT multiplication: q <- Exp(delta) * q.
class VertexSO3 final : public BaseVertex<3, Quat> {
 public:
  explicit VertexSO3(int id, const Quat& q = Quat::Identity()) : BaseVertex(id, q) {}
  Quat plus(const Quat& x, const Delta& delta) const override { return (so3Exp(delta) * x).normalized(); }
};

/// Euclidean vector R^N (3-D point, velocity, IMU bias...), updated by addition.
template <int N>
class VertexVector final : public BaseVertex<N, Eigen::Matrix<double, N, 1>> {
 public:
  using Base = BaseVertex<N, Eigen::Matrix<double, N, 1>>;
  using typename Base::Delta;
  using Vector = Eigen::Matrix<double, N, 1>;
  explicit VertexVector(int id, const Vector& x = Vector::Zero()) : Base(id, x) {}
  Vector plus(const Vector& x, const Delta& delta) const override { return x + delta; }
};
using VertexPoint3 = VertexVector<3>;

/// Pinhole intrinsics in pixels.
struct PinholeIntrinsics {
  double fx = 1.0, fy = 1.0, cx = 0.0, cy = 0.0;
};

/// Reprojection of a world point p_w into a camera with pose T_c_w:
/// error = project(T_c_w * p_w) - measurement (pixels). Vertex 0: VertexSE3 (T_c_w), 1: VertexPoint3.
class EdgeProjectPoint final : public BaseEdge<2, Vec2, VertexSE3, VertexPoint3> {
 public:
  explicit EdgeProjectPoint(const PinholeIntrinsics& intrinsics) : intrinsics_(intrinsics) {}
  void computeError() override;
  void linearizeOplus() override;
  const PinholeIntrinsics& intrinsics() const { return intrinsics_; }

 private:
  PinholeIntrinsics intrinsics_;
};

/// Relative pose between two poses T_w_i (vertex 0) and T_w_j (vertex 1); measurement Z = T_i_j.
/// E = Z^-1 T_w_i^-1 T_w_j; error = [Log(R_E); t_E] (rotation first, rad and m).
class EdgeSE3Relative final : public BaseEdge<6, SE3, VertexSE3, VertexSE3> {
 public:
  void computeError() override;
  void linearizeOplus() override;
};

/// Prior on one pose T (vertex 0) with measurement Z: error = [Log(R_Z^T R); t - t_Z].
class EdgeSE3Prior final : public BaseEdge<6, SE3, VertexSE3> {
 public:
  void computeError() override;
  void linearizeOplus() override;
};

}  // namespace sparse_opt
