#pragma once
/// Inertial, bias random-walk and R^3 prior edges (namespace ltlo::optim). The inertial residual and its
/// Jacobians are imu::inertialResidualJacobians (imu/inertial_residual.h); these edges only chain
/// them to the vertex perturbations of vertices.h.
#include <memory>

#include <sparse_opt/edge.h>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/optim/vertices.h"

namespace ltlo::optim {

/// Symmetrised inverse of a covariance (asserts it is positive definite).
Mat9 informationFromCovariance(const Mat9& covariance);

/// Inertial edge between keyframes i and j. Vertices: 0 pose_i (VertexPose), 1 v_i, 2 b_g, 3 b_a,
/// 4 pose_j, 5 v_j. The biases are the ones the deltas are corrected for (those of i in a window; the
/// current frame's own biases in pose-only tracking). Residual [phi; v; p] (imu::inertialResidual),
/// information = preintegration information (inverse covariance) by default. The preintegration is
/// shared, not copied; it must not change while the edge lives.
class EdgeInertial final
    : public sparse_opt::BaseEdge<9, Vec9, VertexPose, VertexVelocity, VertexGyroBias, VertexAccBias,
                                  VertexPose, VertexVelocity> {
 public:
  explicit EdgeInertial(std::shared_ptr<const imu::Preintegrated> pim, const Vec3& g_w = imu::gravityWorld());
  void computeError() override;
  void linearizeOplus() override;
  const imu::Preintegrated& preintegrated() const { return *pim_; }

 private:
  std::shared_ptr<const imu::Preintegrated> pim_;
  Vec3 g_w_;
};

/// Inertial edge with the gravity direction as a vertex (IMU initialisation):
/// g_w = R_w_g (0, 0, -gravity_m_s2). Vertices 0..5 as EdgeInertial, 6 VertexGravityDir.
class EdgeInertialGravity final
    : public sparse_opt::BaseEdge<9, Vec9, VertexPose, VertexVelocity, VertexGyroBias, VertexAccBias,
                                  VertexPose, VertexVelocity, VertexGravityDir> {
 public:
  explicit EdgeInertialGravity(std::shared_ptr<const imu::Preintegrated> pim,
                               double gravity_m_s2 = imu::kGravity_m_s2);
  void computeError() override;
  void linearizeOplus() override;

 private:
  std::shared_ptr<const imu::Preintegrated> pim_;
  double gravity_m_s2_;
};

/// Information of the bias random walk over interval_s, weighted by lambda_imu (thesis Eq. 58:
/// lambda_imu (|b_g_i - b_g_i-1|^2_Sigma_bg + |b_a_i - b_a_i-1|^2_Sigma_ba)), order [b_g; b_a].
Mat6 biasWalkInformation(const imu::ImuNoise& noise, double interval_s, double lambda_imu = 1.0);

/// Bias random walk between consecutive keyframes: r = [b_g_j - b_g_i; b_a_j - b_a_i].
/// Vertices: 0 b_g_i, 1 b_a_i, 2 b_g_j, 3 b_a_j. Set the information with biasWalkInformation().
class EdgeBiasWalk final
    : public sparse_opt::BaseEdge<6, Vec6, VertexGyroBias, VertexAccBias, VertexGyroBias, VertexAccBias> {
 public:
  void computeError() override;
  void linearizeOplus() override;
};

/// The state of one frame in tracking: body pose, velocity and biases.
struct InertialState {
  SE3 T_w_b;
  Vec3 v_w_b = Vec3::Zero();  ///< m/s
  imu::ImuBias bias;
};

/// Gaussian prior on a whole state (the marginalised previous frame of tracking), measurement
/// x_0 = (T_w_b0, v_0, b_g0, b_a0):
///   r = [Log(R_0^T R); R_0^T (p - p_0); v - v_0; b_g - b_g0; b_a - b_a0],
/// which is the vertex perturbation [dphi; drho; dv; db_g; db_a] at x_0 to first order, so the
/// 15x15 information of a marginal over (VertexPose, VertexVelocity, VertexGyroBias,
/// VertexAccBias) is used as it is. Vertices: 0 pose, 1 v, 2 b_g, 3 b_a.
class EdgeStatePrior final : public sparse_opt::BaseEdge<15, InertialState, VertexPose, VertexVelocity,
                                                         VertexGyroBias, VertexAccBias> {
 public:
  void computeError() override;
  void linearizeOplus() override;
};

/// Prior r = x - measurement on an R^3 vertex (velocity, bias, point).
template <typename Vertex>
class EdgeVec3Prior final : public sparse_opt::BaseEdge<3, Vec3, Vertex> {
 public:
  void computeError() override { this->error_ = this->template estimate<0>() - this->measurement_; }
  void linearizeOplus() override { this->template jacobian<0>().setIdentity(); }
};
using EdgeVelocityPrior = EdgeVec3Prior<VertexVelocity>;
using EdgeGyroBiasPrior = EdgeVec3Prior<VertexGyroBias>;
using EdgeAccBiasPrior = EdgeVec3Prior<VertexAccBias>;

}  // namespace ltlo::optim
