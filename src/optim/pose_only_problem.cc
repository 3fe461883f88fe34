#include "ltlo/optim/pose_only_problem.h"

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

// Vertex ids of the pose-only graph.
enum VertexId : int {
  kPose = 0,
  kVelocity = 1,
  kGyroBias = 2,
  kAccBias = 3,
  kPrevPose = 4,
  kPrevVelocity = 5,
  kPrevGyroBias = 6,
  kPrevAccBias = 7,
};

using ObservationEdge = ReprojectionObservation<RgbdEdge, MonoEdge>;

template <typename V>
V* addVertex(sparse_opt::Graph& graph, std::unique_ptr<V> vertex, bool fixed) {
  vertex->setFixed(fixed);
  return graph.addVertex(std::move(vertex));
}

}  // namespace

PoseOnlyResult optimizePose(const PoseOnlyProblem& problem, const PoseOnlyOptions& options) {
  LTLO_ASSERT(options.rounds >= 1, "optimizePose: rounds = " << options.rounds << ", expected >= 1");
  sparse_opt::Graph graph;
  VertexPose* pose = addVertex(graph, std::make_unique<VertexPose>(kPose, problem.T_w_b_init), false);
  VertexVelocity* velocity = nullptr;
  VertexGyroBias* gyro_bias = nullptr;
  VertexAccBias* acc_bias = nullptr;

  if (problem.inertial) {
    const InertialLink& link = *problem.inertial;
    LTLO_ASSERT(link.pim != nullptr, "optimizePose: inertial link without preintegration");
    velocity = addVertex(graph, std::make_unique<VertexVelocity>(kVelocity, problem.v_w_b_init), false);
    gyro_bias = addVertex(graph, std::make_unique<VertexGyroBias>(kGyroBias, problem.bias_init.b_g), false);
    acc_bias = addVertex(graph, std::make_unique<VertexAccBias>(kAccBias, problem.bias_init.b_a), false);
    const bool prev_fixed = !link.prev_prior.has_value();
    auto* prev_pose = addVertex(graph, std::make_unique<VertexPose>(kPrevPose, link.T_w_b_prev), prev_fixed);
    auto* prev_velocity =
        addVertex(graph, std::make_unique<VertexVelocity>(kPrevVelocity, link.v_w_b_prev), prev_fixed);
    auto* prev_gyro = addVertex(graph, std::make_unique<VertexGyroBias>(kPrevGyroBias, link.bias_prev.b_g), prev_fixed);
    auto* prev_acc = addVertex(graph, std::make_unique<VertexAccBias>(kPrevAccBias, link.bias_prev.b_a), prev_fixed);
    if (link.prev_prior) {
      auto pose_prior = std::make_unique<EdgePosePrior>();
      pose_prior->setVertex(0, prev_pose);
      pose_prior->setMeasurement(link.T_w_b_prev);
      pose_prior->setInformation(link.prev_prior->pose_information);
      graph.addEdge(std::move(pose_prior));
      auto velocity_prior = std::make_unique<EdgeVelocityPrior>();
      velocity_prior->setVertex(0, prev_velocity);
      velocity_prior->setMeasurement(link.v_w_b_prev);
      velocity_prior->setInformation(link.prev_prior->velocity_information);
      graph.addEdge(std::move(velocity_prior));
      auto gyro_prior = std::make_unique<EdgeGyroBiasPrior>();
      gyro_prior->setVertex(0, prev_gyro);
      gyro_prior->setMeasurement(link.bias_prev.b_g);
      gyro_prior->setInformation(link.prev_prior->gyro_bias_information);
      graph.addEdge(std::move(gyro_prior));
      auto acc_prior = std::make_unique<EdgeAccBiasPrior>();
      acc_prior->setVertex(0, prev_acc);
      acc_prior->setMeasurement(link.bias_prev.b_a);
      acc_prior->setInformation(link.prev_prior->acc_bias_information);
      graph.addEdge(std::move(acc_prior));
    }

    // The current frame's biases correct the deltas (ORB-SLAM3's pose-inertial optimisation); the
    // random walk ties them to the previous frame's.
    auto inertial = std::make_unique<EdgeInertial>(link.pim, link.g_w);
    inertial->setVertex(0, prev_pose);
    inertial->setVertex(1, prev_velocity);
    inertial->setVertex(2, gyro_bias);
    inertial->setVertex(3, acc_bias);
    inertial->setVertex(4, pose);
    inertial->setVertex(5, velocity);
    graph.addEdge(std::move(inertial));

    auto walk = std::make_unique<EdgeBiasWalk>();
    walk->setVertex(0, prev_gyro);
    walk->setVertex(1, prev_acc);
    walk->setVertex(2, gyro_bias);
    walk->setVertex(3, acc_bias);
    walk->setInformation(biasWalkInformation(link.pim->noise(), std::max(link.pim->dt_s(), 1e-3), link.lambda_imu));
    graph.addEdge(std::move(walk));
  }

  std::vector<ObservationEdge> edges;
  edges.reserve(problem.observations.size());
  for (const PoseObservation& obs : problem.observations) {
    LTLO_ASSERT(obs.sigma_px > 0.0, "optimizePose: sigma_px = " << obs.sigma_px << ", expected > 0");
    const double inv_sigma2 = 1.0 / (obs.sigma_px * obs.sigma_px);
    ObservationEdge entry;
    if (obs.depth_m > 0.0) {
      auto edge = std::make_unique<RgbdEdge>(problem.model, obs.p_w);
      edge->setVertex(0, pose);
      edge->setMeasurement(problem.model.rgbdObservation(obs.uv, obs.depth_m));
      edge->setObservationInformation(inv_sigma2 * Mat3::Identity());
      edge->setStaticWeight(obs.static_weight);
      edge->setRobustKernel(std::make_unique<sparse_opt::HuberKernel>(std::sqrt(options.chi2_3d)));
      entry.rgbd = graph.addEdge(std::move(edge));
      entry.edge = entry.rgbd;
      entry.threshold = options.chi2_3d;
    } else {
      auto edge = std::make_unique<MonoEdge>(problem.model, obs.p_w);
      edge->setVertex(0, pose);
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

  result.T_w_b = pose->estimate();
  // Information of the current pose: inverse of its marginal covariance at the final estimate.
  // An unconstrained pose (too few inliers, no IMU) has no covariance: the information stays zero.
  try {
    const std::vector<Eigen::MatrixXd> covariance = graph.marginalCovariance({kPose}, solver_options);
    const Mat6 cov = covariance.at(0);
    result.pose_information = cov.ldlt().solve(Mat6::Identity());
  } catch (const sparse_opt::Error& error) {
    log::debug("optimizePose: no pose information (", result.num_inliers, " inliers): ", error.what());
  }
  if (problem.inertial) {
    result.v_w_b = velocity->estimate();
    result.bias.b_g = gyro_bias->estimate();
    result.bias.b_a = acc_bias->estimate();
  } else {
    result.v_w_b = problem.v_w_b_init;
    result.bias = problem.bias_init;
  }
  return result;
}

}  // namespace ltlo::optim
