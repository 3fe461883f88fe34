#pragma once
/// Pose graphs (essential graph / loop closing, namespace ltlo::optim) on plain inputs: body poses
/// T_w_b linked by relative-pose measurements T_i_j. No scale: depth fixes it. Without a known
/// gravity direction the poses have 6 DoF (EdgeRelativePose); with it, 4 DoF (yaw about gravity and
/// translation, EdgeYawRelativePose), because roll and pitch are observable through gravity.
#include <vector>

#include <sparse_opt/graph.h>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"

namespace ltlo::optim {

struct PoseGraphNode {
  int id = 0;
  SE3 T_w_b;
  bool fixed = false;  ///< e.g. the loop keyframe (gauge)
};

/// Relative-pose measurement T_i_j = T_w_i^-1 T_w_j with information on r = [Log(R_E); t_E]
/// (rotation first, see EdgeRelativePose).
struct PoseGraphEdge {
  int id_i = 0;
  int id_j = 0;
  SE3 T_i_j;
  Mat6 information = Mat6::Identity();
};

struct PoseGraphResult {
  std::vector<PoseGraphNode> nodes;  ///< input order, optimised poses
  sparse_opt::Summary summary;
};

/// Asserts on unknown or duplicate ids.
PoseGraphResult optimizePoseGraph(const std::vector<PoseGraphNode>& nodes, const std::vector<PoseGraphEdge>& edges,
                                  int iterations = 20);

/// The same graph with 4-DoF poses (VertexYawPose about up_w = -g_w / |g_w|): each node keeps its
/// roll and pitch relative to gravity exactly; the residuals and informations are those of
/// optimizePoseGraph. Asserts on unknown or duplicate ids and on a zero g_w.
PoseGraphResult optimizePoseGraph4Dof(const std::vector<PoseGraphNode>& nodes, const std::vector<PoseGraphEdge>& edges,
                                      const Vec3& g_w, int iterations = 20);

/// The rotation about `axis_w` (need not be unit) nearest to R: the twist of R's swing-twist
/// decomposition about the axis (the vector part of R's quaternion projected on the axis). For
/// R = Exp(axis_w yaw) it is R itself; for a half turn about an axis normal to axis_w, identity.
Quat twistAbout(const Quat& R, const Vec3& axis_w);

/// The part of a world correction T_new_old (poses T_w_b_new = T_new_old * T_w_b_old) a map with
/// known gravity may take: its rotation reduced to the yaw about -g_w (twistAbout), its translation
/// chosen so that `anchor_w` (m, e.g. the position of the keyframe that defined the correction) goes
/// where T_new_old takes it.
SE3 fourDofCorrection(const SE3& T_new_old, const Vec3& g_w, const Vec3& anchor_w);

}  // namespace ltlo::optim
