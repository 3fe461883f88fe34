#pragma once
/// 4-DoF body poses and their relative-pose edge (namespace ltlo::optim): the essential graph of a
/// map whose gravity direction is known. Roll and pitch are observable through gravity, so a loop
/// correction may only turn the map about the gravity axis (yaw) and move it (translation).
#include <sparse_opt/edge.h>
#include <sparse_opt/vertex.h>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"

namespace ltlo::optim {

/// Body pose T_w_b with four degrees of freedom, delta = [d_yaw; d_p]:
///   R_w_b <- Exp(up_w d_yaw) R_w_b    (turn about the world's up axis: roll and pitch relative to
///                                      gravity stay as given)
///   p_w_b <- p_w_b + d_p              (world frame)
/// up_w is the unit vector opposite to gravity, g_w = -|g| up_w.
class VertexYawPose final : public sparse_opt::BaseVertex<4, SE3> {
 public:
  VertexYawPose(int id, const SE3& T_w_b, const Vec3& up_w);
  SE3 plus(const SE3& T_w_b, const Delta& delta) const override;
  const Vec3& up_w() const { return up_w_; }

 private:
  Vec3 up_w_;
};

/// Relative body pose between two 4-DoF poses, measurement T_i_j (the pose of j in i):
///   r = [Log(R_ij^T R_w_i^T R_w_j); R_w_i^T (p_w_j - p_w_i) - t_ij]  (rotation first, as
/// EdgeRelativePose, so the same 6x6 information applies). Vertices 0 pose_i, 1 pose_j, both with
/// the same up_w.
class EdgeYawRelativePose final : public sparse_opt::BaseEdge<6, SE3, VertexYawPose, VertexYawPose> {
 public:
  void computeError() override;
  void linearizeOplus() override;
};

}  // namespace ltlo::optim
