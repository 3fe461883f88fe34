#include "ltlo/optim/bundle_adjust.h"

#include <Eigen/Dense>
#include <cmath>

#include "ltlo/core/assert.h"
#include "ltlo/optim/inertial_edges.h"
#include "ltlo/optim/local_ba_graph.h"
#include "ltlo/optim/vertices.h"

namespace ltlo::optim {

LocalBaResult localBundleAdjust(const LocalBaProblem& problem, const LocalBaOptions& options) {
  LocalBaGraph graph(problem, options);
  sparse_opt::Summary summary = graph.optimize(options.iterations);
  const bool stopped = options.stop_flag != nullptr && options.stop_flag->load();
  if (options.reject_outliers && !stopped) {
    graph.rejectOutliers();
    summary = graph.optimize(options.iterations);
  }
  return graph.result(summary);
}

ImuInitResult linearImuInit(const ImuInitProblem& problem) {
  const int n = static_cast<int>(problem.T_w_b.size());
  LTLO_ASSERT(n >= 3, "linearImuInit: " << n << " keyframes, expected >= 3");
  LTLO_ASSERT(static_cast<int>(problem.pims.size()) == n - 1,
              "linearImuInit: " << problem.pims.size() << " preintegrations for " << n << " keyframes");
  // Unknowns x = [v_0 .. v_n-1, g_w]; per interval k -> k+1 (deltas at bias_init):
  //   v_k+1 - v_k - g dt = R_k dv,   v_k dt + g dt^2/2 = p_k+1 - p_k - R_k dp.
  MatX A = MatX::Zero(6 * (n - 1), 3 * n + 3);
  VecX b = VecX::Zero(6 * (n - 1));
  for (int k = 0; k + 1 < n; ++k) {
    const imu::Preintegrated& pim = *problem.pims[static_cast<size_t>(k)];
    const double dt = pim.dt_s();
    const Mat3 R_k = problem.T_w_b[static_cast<size_t>(k)].rotationMatrix();
    const Vec3 p_k = problem.T_w_b[static_cast<size_t>(k)].translation();
    const Vec3 p_k1 = problem.T_w_b[static_cast<size_t>(k + 1)].translation();
    const int row = 6 * k;
    // Rows scaled by 1/dt so both equations are in m/s.
    A.block<3, 3>(row, 3 * (k + 1)) = Mat3::Identity();
    A.block<3, 3>(row, 3 * k) = -Mat3::Identity();
    A.block<3, 3>(row, 3 * n) = -dt * Mat3::Identity();
    b.segment<3>(row) = R_k * pim.correctedDeltaV(problem.bias_init);
    A.block<3, 3>(row + 3, 3 * k) = Mat3::Identity();
    A.block<3, 3>(row + 3, 3 * n) = 0.5 * dt * Mat3::Identity();
    b.segment<3>(row + 3) = (p_k1 - p_k - R_k * pim.correctedDeltaP(problem.bias_init)) / dt;
  }
  const VecX x = A.colPivHouseholderQr().solve(b);
  ImuInitResult result;
  result.bias = problem.bias_init;
  for (int k = 0; k < n; ++k) result.v_w_b.push_back(x.segment<3>(3 * k));
  const Vec3 g_w = x.segment<3>(3 * n);
  result.R_w_g = imu::gravityRotationFromDirection(g_w);
  result.g_w = imu::gravityFromRotation(result.R_w_g, problem.gravity_m_s2);
  return result;
}

ImuInitResult initializeImu(const ImuInitProblem& problem) {
  ImuInitResult result = linearImuInit(problem);
  const int n = static_cast<int>(problem.T_w_b.size());
  sparse_opt::Graph graph;
  // Ids: pose k = 2k, velocity k = 2k+1, then biases and gravity.
  std::vector<VertexPose*> poses;
  std::vector<VertexVelocity*> velocities;
  for (int k = 0; k < n; ++k) {
    auto pose = std::make_unique<VertexPose>(2 * k, problem.T_w_b[static_cast<size_t>(k)]);
    pose->setFixed(true);
    poses.push_back(graph.addVertex(std::move(pose)));
    velocities.push_back(graph.addVertex(std::make_unique<VertexVelocity>(2 * k + 1, result.v_w_b[static_cast<size_t>(k)])));
  }
  auto* gyro_bias = graph.addVertex(std::make_unique<VertexGyroBias>(2 * n, problem.bias_init.b_g));
  auto* acc_bias = graph.addVertex(std::make_unique<VertexAccBias>(2 * n + 1, problem.bias_init.b_a));
  auto* gravity = graph.addVertex(std::make_unique<VertexGravityDir>(2 * n + 2, result.R_w_g));
  for (int k = 0; k + 1 < n; ++k) {
    auto edge = std::make_unique<EdgeInertialGravity>(problem.pims[static_cast<size_t>(k)], problem.gravity_m_s2);
    edge->setVertex(0, poses[static_cast<size_t>(k)]);
    edge->setVertex(1, velocities[static_cast<size_t>(k)]);
    edge->setVertex(2, gyro_bias);
    edge->setVertex(3, acc_bias);
    edge->setVertex(4, poses[static_cast<size_t>(k + 1)]);
    edge->setVertex(5, velocities[static_cast<size_t>(k + 1)]);
    edge->setVertex(6, gravity);
    graph.addEdge(std::move(edge));
  }
  auto gyro_prior = std::make_unique<EdgeGyroBiasPrior>();
  gyro_prior->setVertex(0, gyro_bias);
  gyro_prior->setMeasurement(Vec3::Zero());
  gyro_prior->setInformation(problem.gyro_bias_prior_information * Mat3::Identity());
  graph.addEdge(std::move(gyro_prior));
  auto acc_prior = std::make_unique<EdgeAccBiasPrior>();
  acc_prior->setVertex(0, acc_bias);
  acc_prior->setMeasurement(Vec3::Zero());
  acc_prior->setInformation(problem.acc_bias_prior_information * Mat3::Identity());
  graph.addEdge(std::move(acc_prior));

  sparse_opt::Options options;
  options.max_iterations = problem.iterations;
  options.use_schur = false;
  options.num_threads = 1;
  result.summary = graph.optimize(options);

  result.R_w_g = gravity->estimate();
  result.g_w = imu::gravityFromRotation(result.R_w_g, problem.gravity_m_s2);
  result.bias.b_g = gyro_bias->estimate();
  result.bias.b_a = acc_bias->estimate();
  for (int k = 0; k < n; ++k) result.v_w_b[static_cast<size_t>(k)] = velocities[static_cast<size_t>(k)]->estimate();
  return result;
}

}  // namespace ltlo::optim
