#pragma once
/// SE3 pose graph (essential graph / loop closing, namespace ltlo::optim) on plain inputs: body poses
/// T_w_b linked by relative-pose measurements T_i_j (EdgeRelativePose). No scale: depth fixes it.
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

}  // namespace ltlo::optim
