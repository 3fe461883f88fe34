#include "ltlo/optim/pose_graph.h"

#include <cmath>
#include <memory>
#include <unordered_map>

#include "ltlo/core/assert.h"
#include "ltlo/optim/pose_edges.h"
#include "ltlo/optim/vertices.h"
#include "ltlo/optim/yaw_pose_edges.h"

namespace ltlo::optim {

PoseGraphResult optimizePoseGraph(const std::vector<PoseGraphNode>& nodes, const std::vector<PoseGraphEdge>& edges,
                                  int iterations) {
  sparse_opt::Graph graph;
  std::unordered_map<int, VertexPose*> vertices;
  std::vector<VertexPose*> in_order;
  for (size_t k = 0; k < nodes.size(); ++k) {
    auto vertex = std::make_unique<VertexPose>(static_cast<int>(k), nodes[k].T_w_b);
    vertex->setFixed(nodes[k].fixed);
    VertexPose* raw = graph.addVertex(std::move(vertex));
    LTLO_ASSERT(vertices.emplace(nodes[k].id, raw).second, "optimizePoseGraph: duplicate node id " << nodes[k].id);
    in_order.push_back(raw);
  }
  auto find = [&](int id) {
    const auto it = vertices.find(id);
    LTLO_ASSERT(it != vertices.end(), "optimizePoseGraph: unknown node id " << id);
    return it->second;
  };
  for (const PoseGraphEdge& measurement : edges) {
    auto edge = std::make_unique<EdgeRelativePose>();
    edge->setVertex(0, find(measurement.id_i));
    edge->setVertex(1, find(measurement.id_j));
    edge->setMeasurement(measurement.T_i_j);
    edge->setInformation(measurement.information);
    graph.addEdge(std::move(edge));
  }
  sparse_opt::Options options;
  options.max_iterations = iterations;
  options.use_schur = false;
  PoseGraphResult result;
  result.summary = graph.optimize(options);
  result.nodes = nodes;
  for (size_t k = 0; k < nodes.size(); ++k) result.nodes[k].T_w_b = in_order[k]->estimate();
  return result;
}

PoseGraphResult optimizePoseGraph4Dof(const std::vector<PoseGraphNode>& nodes, const std::vector<PoseGraphEdge>& edges,
                                      const Vec3& g_w, int iterations) {
  LTLO_ASSERT(g_w.allFinite() && g_w.norm() > 0.0, "optimizePoseGraph4Dof: g_w = " << g_w.transpose());
  const Vec3 up_w = -g_w.normalized();
  sparse_opt::Graph graph;
  std::unordered_map<int, VertexYawPose*> vertices;
  std::vector<VertexYawPose*> in_order;
  for (size_t k = 0; k < nodes.size(); ++k) {
    auto vertex = std::make_unique<VertexYawPose>(static_cast<int>(k), nodes[k].T_w_b, up_w);
    vertex->setFixed(nodes[k].fixed);
    VertexYawPose* raw = graph.addVertex(std::move(vertex));
    LTLO_ASSERT(vertices.emplace(nodes[k].id, raw).second, "optimizePoseGraph4Dof: duplicate node id " << nodes[k].id);
    in_order.push_back(raw);
  }
  auto find = [&](int id) {
    const auto it = vertices.find(id);
    LTLO_ASSERT(it != vertices.end(), "optimizePoseGraph4Dof: unknown node id " << id);
    return it->second;
  };
  for (const PoseGraphEdge& measurement : edges) {
    auto edge = std::make_unique<EdgeYawRelativePose>();
    edge->setVertex(0, find(measurement.id_i));
    edge->setVertex(1, find(measurement.id_j));
    edge->setMeasurement(measurement.T_i_j);
    edge->setInformation(measurement.information);
    graph.addEdge(std::move(edge));
  }
  sparse_opt::Options options;
  options.max_iterations = iterations;
  options.use_schur = false;
  PoseGraphResult result;
  result.summary = graph.optimize(options);
  result.nodes = nodes;
  for (size_t k = 0; k < nodes.size(); ++k) result.nodes[k].T_w_b = in_order[k]->estimate();
  return result;
}

Quat twistAbout(const Quat& R, const Vec3& axis_w) {
  const Vec3 axis = axis_w.normalized();
  const Vec3 along = axis * axis.dot(R.vec());
  const double norm = std::sqrt(R.w() * R.w() + along.squaredNorm());
  if (norm < 1e-12) return Quat::Identity();
  return Quat(R.w() / norm, along.x() / norm, along.y() / norm, along.z() / norm);
}

SE3 fourDofCorrection(const SE3& T_new_old, const Vec3& g_w, const Vec3& anchor_w) {
  LTLO_ASSERT(g_w.allFinite() && g_w.norm() > 0.0, "fourDofCorrection: g_w = " << g_w.transpose());
  const Quat yaw = twistAbout(T_new_old.quaternion(), g_w);
  return SE3(yaw, T_new_old * anchor_w - yaw * anchor_w);
}

}  // namespace ltlo::optim
