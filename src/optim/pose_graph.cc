#include "ltlo/optim/pose_graph.h"

#include <memory>
#include <unordered_map>

#include "ltlo/core/assert.h"
#include "ltlo/optim/pose_edges.h"
#include "ltlo/optim/vertices.h"

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

}  // namespace ltlo::optim
