#include "ltlo/optim/pose_only_problem.h"

#include <Eigen/Cholesky>
#include <array>
#include <cmath>
#include <sparse_opt/graph.h>
#include <sparse_opt/robust_kernel.h>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/optim/inertial_edges.h"
#include "ltlo/optim/pose_edges.h"
#include "ltlo/optim/vertices.h"
#include "observation_edge.h"

namespace ltlo::optim {

namespace {

using RgbdEdge = EdgeRgbdReprojectionPoseOnly<VertexPose>;
using MonoEdge = EdgeMonoReprojectionPoseOnly<VertexPose>;

// Vertex ids of the pose-only graph, and their offsets in the dense state [current; previous]
// (each 15 = pose 6, velocity 3, gyro bias 3, accelerometer bias 3).
enum VertexId : int {
  kPose = 0,
  kVelocity = 1,
  kGyroBias = 2,
  kAccBias = 3,
  kPrevPose = 4,
  kPrevVelocity = 5,
  kPrevGyroBias = 6,
  kPrevAccBias = 7,
  kNumVertexIds = 8,
};
constexpr std::array<int, kNumVertexIds> kStateOffset = {0, 6, 9, 12, 15, 21, 24, 27};
constexpr int kStateDim = 15;

using ObservationEdge = ReprojectionObservation<RgbdEdge, MonoEdge>;

template <typename V>
V* addVertex(sparse_opt::Graph& graph, std::unique_ptr<V> vertex, bool fixed) {
  vertex->setFixed(fixed);
  return graph.addVertex(std::move(vertex));
}

/// The current state's vertices (velocity and biases only with the IMU).
struct CurrentVertices {
  VertexPose* pose = nullptr;
  VertexVelocity* velocity = nullptr;
  VertexGyroBias* gyro_bias = nullptr;
  VertexAccBias* acc_bias = nullptr;
};

CurrentVertices addCurrentState(sparse_opt::Graph& graph, const InertialState& state, bool inertial) {
  CurrentVertices current;
  current.pose = addVertex(graph, std::make_unique<VertexPose>(kPose, state.T_w_b), false);
  if (inertial) {
    current.velocity = addVertex(graph, std::make_unique<VertexVelocity>(kVelocity, state.v_w_b), false);
    current.gyro_bias = addVertex(graph, std::make_unique<VertexGyroBias>(kGyroBias, state.bias.b_g), false);
    current.acc_bias = addVertex(graph, std::make_unique<VertexAccBias>(kAccBias, state.bias.b_a), false);
  }
  return current;
}

// The previous state (fixed, or free under its prior), the inertial edge previous -> current and
// the bias random walk (thesis Eq. 58).
void addInertialLink(sparse_opt::Graph& graph, const InertialLink& link, const CurrentVertices& current) {
  LTLO_ASSERT(link.pim != nullptr, "optimizePose: inertial link without preintegration");
  const bool prev_fixed = !link.prev_prior.has_value();
  auto* prev_pose = addVertex(graph, std::make_unique<VertexPose>(kPrevPose, link.T_w_b_prev), prev_fixed);
  auto* prev_velocity = addVertex(graph, std::make_unique<VertexVelocity>(kPrevVelocity, link.v_w_b_prev),
                                  prev_fixed && !link.prev_velocity_free);
  auto* prev_gyro = addVertex(graph, std::make_unique<VertexGyroBias>(kPrevGyroBias, link.bias_prev.b_g), prev_fixed);
  auto* prev_acc = addVertex(graph, std::make_unique<VertexAccBias>(kPrevAccBias, link.bias_prev.b_a), prev_fixed);
  if (link.prev_prior) {
    auto prior = std::make_unique<EdgeStatePrior>();
    prior->setVertex(0, prev_pose);
    prior->setVertex(1, prev_velocity);
    prior->setVertex(2, prev_gyro);
    prior->setVertex(3, prev_acc);
    prior->setMeasurement(InertialState{link.T_w_b_prev, link.v_w_b_prev, link.bias_prev});
    prior->setInformation(0.5 * (link.prev_prior->information + link.prev_prior->information.transpose()));
    graph.addEdge(std::move(prior));
  } else if (link.prev_velocity_free && link.prev_velocity_information) {
    auto prior = std::make_unique<EdgeVelocityPrior>();
    prior->setVertex(0, prev_velocity);
    prior->setMeasurement(link.v_w_b_prev);
    prior->setInformation(0.5 * (*link.prev_velocity_information + link.prev_velocity_information->transpose()));
    graph.addEdge(std::move(prior));
  }

  // The current frame's biases correct the deltas (ORB-SLAM3's pose-inertial optimisation); the
  // random walk ties them to the previous frame's.
  auto inertial = std::make_unique<EdgeInertial>(link.pim, link.g_w);
  inertial->setVertex(0, prev_pose);
  inertial->setVertex(1, prev_velocity);
  inertial->setVertex(2, current.gyro_bias);
  inertial->setVertex(3, current.acc_bias);
  inertial->setVertex(4, current.pose);
  inertial->setVertex(5, current.velocity);
  graph.addEdge(std::move(inertial));

  auto walk = std::make_unique<EdgeBiasWalk>();
  walk->setVertex(0, prev_gyro);
  walk->setVertex(1, prev_acc);
  walk->setVertex(2, current.gyro_bias);
  walk->setVertex(3, current.acc_bias);
  walk->setInformation(biasWalkInformation(link.pim->noise(), std::max(link.pim->dt_s(), imu::kMinBiasWalkInterval_s), link.lambda_imu));
  graph.addEdge(std::move(walk));
}

// Gauss-Newton Hessian J^T W J of the level-0 edges at the current estimates over the free
// vertices of the dense state [current; previous] (kStateOffset), 2 * kStateDim square. Robust
// weights are those of the edges' kernels (none in the last round of optimizePose).
MatX stateHessian(sparse_opt::Graph& graph) {
  MatX H = MatX::Zero(2 * kStateDim, 2 * kStateDim);
  std::array<double, 36> block{};
  for (sparse_opt::EdgeBase* edge : graph.edges()) {
    if (edge->level() != 0) continue;
    edge->linearize();
    for (int a = 0; a < edge->numVertices(); ++a) {
      const sparse_opt::VertexBase* va = edge->vertex(a);
      if (va->fixed() || va->id() < 0 || va->id() >= kNumVertexIds) continue;
      for (int b = 0; b < edge->numVertices(); ++b) {
        const sparse_opt::VertexBase* vb = edge->vertex(b);
        if (vb->fixed() || vb->id() < 0 || vb->id() >= kNumVertexIds) continue;
        const int da = va->dimension();
        const int db = vb->dimension();
        std::fill(block.begin(), block.begin() + da * db, 0.0);
        edge->addHessianBlock(a, b, block.data());
        H.block(kStateOffset[static_cast<std::size_t>(va->id())], kStateOffset[static_cast<std::size_t>(vb->id())], da,
                db) += Eigen::Map<const MatX>(block.data(), da, db);
      }
    }
  }
  return 0.5 * (H + H.transpose());
}

// The current state's marginal: the free vertices of the previous state (under its prior, or a
// free velocity) Schur-complemented out.
Mat15 currentStateInformation(sparse_opt::Graph& graph) {
  const MatX H = stateHessian(graph);
  std::vector<int> keep;
  for (int i = 0; i < kStateDim; ++i) keep.push_back(i);
  for (int id = kPrevPose; id < kNumVertexIds; ++id) {
    const sparse_opt::VertexBase* vertex = graph.vertex(id);
    if (vertex == nullptr || vertex->fixed()) continue;
    for (int i = 0; i < vertex->dimension(); ++i) keep.push_back(kStateOffset[static_cast<std::size_t>(id)] + i);
  }
  if (static_cast<int>(keep.size()) == kStateDim) return H.topLeftCorner<kStateDim, kStateDim>();
  const int n = static_cast<int>(keep.size());
  MatX selected(n, n);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) selected(r, c) = H(keep[static_cast<std::size_t>(r)], keep[static_cast<std::size_t>(c)]);
  }
  return marginalInformation(selected, kStateDim);
}

bool isPositiveDefinite(const Mat6& information) {
  const Eigen::LDLT<Mat6> ldlt(information);
  return ldlt.info() == Eigen::Success && ldlt.isPositive() && ldlt.vectorD().minCoeff() > 0.0;
}

}  // namespace

MatX marginalInformation(const MatX& information, int keep) {
  const int n = static_cast<int>(information.rows());
  LTLO_ASSERT(information.cols() == n && keep > 0 && keep <= n,
              "marginalInformation: " << information.rows() << "x" << information.cols() << ", keep " << keep);
  if (keep == n) return information;
  const int drop = n - keep;
  const Eigen::LDLT<MatX> ldlt(information.bottomRightCorner(drop, drop));
  LTLO_ASSERT(ldlt.info() == Eigen::Success, "marginalInformation: the marginalised block is not positive definite");
  const MatX schur = information.topLeftCorner(keep, keep) -
                     information.topRightCorner(keep, drop) * ldlt.solve(information.bottomLeftCorner(drop, keep));
  return 0.5 * (schur + schur.transpose());
}

Mat15 predictedStateInformation(const InertialLink& link, const InertialState& current) {
  sparse_opt::Graph graph;
  const CurrentVertices vertices = addCurrentState(graph, current, true);
  addInertialLink(graph, link, vertices);
  return currentStateInformation(graph);
}

PoseOnlyResult optimizePose(const PoseOnlyProblem& problem, const PoseOnlyOptions& options) {
  LTLO_ASSERT(options.rounds >= 1, "optimizePose: rounds = " << options.rounds << ", expected >= 1");
  sparse_opt::Graph graph;
  const CurrentVertices current = addCurrentState(
      graph, InertialState{problem.T_w_b_init, problem.v_w_b_init, problem.bias_init}, problem.inertial.has_value());
  if (problem.inertial) addInertialLink(graph, *problem.inertial, current);

  std::vector<ObservationEdge> edges;
  edges.reserve(problem.observations.size());
  for (const PoseObservation& obs : problem.observations) {
    LTLO_ASSERT(obs.sigma_px > 0.0, "optimizePose: sigma_px = " << obs.sigma_px << ", expected > 0");
    const double inv_sigma2 = 1.0 / (obs.sigma_px * obs.sigma_px);
    ObservationEdge entry;
    if (obs.depth_m > 0.0) {
      auto edge = std::make_unique<RgbdEdge>(problem.model, obs.p_w);
      edge->setVertex(0, current.pose);
      edge->setMeasurement(problem.model.rgbdObservation(obs.uv, obs.depth_m));
      edge->setObservationInformation(inv_sigma2 * Mat3::Identity());
      edge->setStaticWeight(obs.static_weight);
      edge->setRobustKernel(std::make_unique<sparse_opt::HuberKernel>(std::sqrt(options.chi2_3d)));
      entry.rgbd = graph.addEdge(std::move(edge));
      entry.edge = entry.rgbd;
      entry.threshold = options.chi2_3d;
    } else {
      auto edge = std::make_unique<MonoEdge>(problem.model, obs.p_w);
      edge->setVertex(0, current.pose);
      edge->setMeasurement(obs.uv);
      edge->setObservationInformation(inv_sigma2 * Mat2::Identity());
      edge->setStaticWeight(obs.static_weight);
      edge->setRobustKernel(std::make_unique<sparse_opt::HuberKernel>(std::sqrt(options.chi2_2d)));
      entry.mono = graph.addEdge(std::move(edge));
      entry.edge = entry.mono;
      entry.threshold = options.chi2_2d;
    }
    edges.push_back(entry);
  }

  sparse_opt::Options solver_options;
  solver_options.max_iterations = options.iterations_per_round;
  solver_options.num_threads = options.num_threads;
  solver_options.use_schur = false;

  PoseOnlyResult result;
  result.inliers.assign(edges.size(), true);
  for (int round = 0; round < options.rounds; ++round) {
    const sparse_opt::Summary summary = graph.optimize(solver_options);
    result.final_chi2 = summary.final_chi2;
    result.num_inliers = 0;
    for (size_t k = 0; k < edges.size(); ++k) {
      bool depth_positive = false;
      const double chi2 = edges[k].unweightedChi2(&depth_positive);
      const bool inlier = depth_positive && chi2 <= edges[k].threshold;
      result.inliers[k] = inlier;
      edges[k].edge->setLevel(inlier ? 0 : 1);
      if (inlier) ++result.num_inliers;
      // The last round runs on the inliers without the kernel (ORB-SLAM's pose optimisation).
      if (round + 2 >= options.rounds) edges[k].edge->setRobustKernel(nullptr);
    }
    if (result.num_inliers < 3 && !problem.inertial) break;  // too few to constrain the pose
  }

  result.T_w_b = current.pose->estimate();
  if (problem.inertial) {
    result.v_w_b = current.velocity->estimate();
    result.bias.b_g = current.gyro_bias->estimate();
    result.bias.b_a = current.acc_bias->estimate();
    // The marginal of the current state at the final estimate (the next frame's prior).
    result.state_information = currentStateInformation(graph);
    result.pose_information = marginalInformation(result.state_information, 6);
  } else {
    result.v_w_b = problem.v_w_b_init;
    result.bias = problem.bias_init;
    // An unconstrained pose (too few inliers, no IMU) has no information: it stays zero.
    const Mat6 H = stateHessian(graph).topLeftCorner<6, 6>();
    if (isPositiveDefinite(H)) {
      result.pose_information = H;
    } else {
      log::debug("optimizePose: no pose information (", result.num_inliers, " inliers)");
    }
  }
  return result;
}

}  // namespace ltlo::optim
