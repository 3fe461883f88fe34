#pragma once
/// SE3 edges on body poses (namespace ltlo::optim): a pose prior (tracking against a marginalised
/// previous frame) and the relative pose of the essential / pose graph (loop closing).
#include <sparse_opt/edge.h>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/optim/vertices.h"

namespace ltlo::optim {

/// Prior on a body pose with measurement T_w_b0: r = [Log(R_0^T R); R_0^T (p - p_0)], which is
/// the vertex perturbation [dphi; drho] at T_w_b0 to first order, so the 6x6 information of a
/// marginal covariance of a VertexPose is used as it is.
class EdgePosePrior final : public sparse_opt::BaseEdge<6, SE3, VertexPose> {
 public:
  void computeError() override;
  void linearizeOplus() override;
};

/// Relative body pose for the essential / pose graph: measurement T_i_j (the pose of j in i).
/// E = T_i_j^-1 T_w_i^-1 T_w_j, r = [Log(R_E); t_E] (rotation first). Vertices 0 pose_i, 1 pose_j.
class EdgeRelativePose final : public sparse_opt::BaseEdge<6, SE3, VertexPose, VertexPose> {
 public:
  void computeError() override;
  void linearizeOplus() override;
};

}  // namespace ltlo::optim
