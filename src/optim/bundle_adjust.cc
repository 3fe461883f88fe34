#include "ltlo/optim/bundle_adjust.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "ltlo/core/assert.h"
#include "ltlo/optim/inertial_edges.h"
#include "ltlo/optim/local_ba_graph.h"
#include "ltlo/optim/vertices.h"

namespace ltlo::optim {

LocalBaResult localBundleAdjust(const LocalBaProblem& problem, const LocalBaOptions& options) {
  LocalBaGraph graph(problem, options);
  sparse_opt::Summary summary = graph.optimize(options.iterations);
  const double initial_chi2 = summary.initial_chi2;
  const bool stopped = options.stop_flag != nullptr && options.stop_flag->load();
  if (options.reject_outliers && !stopped) {
    graph.rejectOutliers();
    summary = graph.optimize(options.iterations);
  }
  LocalBaResult result = graph.result(summary);
  result.initial_chi2 = initial_chi2;
  return result;
}

double visualVarianceFactor(const LocalBaProblem& problem) {
  // Medians of the chi-square distribution with 2 and 3 degrees of freedom.
  constexpr double kMedianChi2_2 = 1.3863;
  constexpr double kMedianChi2_3 = 2.3660;
  std::unordered_map<int, const BaKeyFrame*> keyframes;
  for (const BaKeyFrame& kf : problem.keyframes) keyframes.emplace(kf.id, &kf);
  std::unordered_map<int, const BaPoint*> points;
  for (const BaPoint& point : problem.points) points.emplace(point.id, &point);
  std::vector<double> ratios;
  ratios.reserve(problem.observations.size());
  for (const BaObservation& obs : problem.observations) {
    if (obs.static_weight < 0.5 || obs.sigma_px <= 0.0) continue;  // dynamic or doubtful: not noise
    const auto kf = keyframes.find(obs.keyframe_id);
    const auto point = points.find(obs.point_id);
    if (kf == keyframes.end() || point == points.end()) continue;
    const Vec3 p_c = problem.model.T_c_x * (kf->second->T_w_b.inverse() * point->second->p_w);
    if (p_c.z() <= 0.0) continue;
    const double inv_sigma2 = 1.0 / (obs.sigma_px * obs.sigma_px);
    if (obs.depth_m > 0.0) {
      const Vec3 r = problem.model.rgbdObservation(obs.uv, obs.depth_m) - problem.model.projectRgbd(p_c);
      ratios.push_back(r.squaredNorm() * inv_sigma2 / kMedianChi2_3);
    } else {
      const Vec2 r = obs.uv - problem.model.project(p_c);
      ratios.push_back(r.squaredNorm() * inv_sigma2 / kMedianChi2_2);
    }
  }
  if (ratios.size() < 10) return 1.0;
  const auto middle = ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2);
  std::nth_element(ratios.begin(), middle, ratios.end());
  return *middle;
}

double inertialInformationScale(const LocalBaProblem& problem) {
  return std::clamp(visualVarianceFactor(problem), 1e-2, 1e2);
}

BiasPriorInformation biasPriorInformation(const imu::ImuNoise& noise, double window_s, double samples) {
  LTLO_ASSERT(window_s >= 0.0 && samples >= 0.0,
              "biasPriorInformation: window_s = " << window_s << ", samples = " << samples);
  BiasPriorInformation information;
  if (samples <= 0.0) return information;
  const Mat6 walk = noise.biasWalkCovariance(std::max(window_s, 0.0));
  const double gyro_variance = noise.gyroCovariance()(0, 0) / samples + walk(0, 0);
  const double acc_variance = noise.accCovariance()(0, 0) / samples + walk(3, 3);
  information.gyro = 1.0 / gyro_variance;
  information.acc = 1.0 / acc_variance;
  return information;
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

namespace {

/// The inertial-only initialisation's graph (Campos et al. 2021 §V-B): keyframe poses held,
/// velocities, one bias pair and the gravity direction free.
struct ImuInitGraph {
  sparse_opt::Graph graph;
  std::vector<VertexVelocity*> velocities;
  VertexGyroBias* gyro_bias = nullptr;
  VertexAccBias* acc_bias = nullptr;
  VertexGravityDir* gravity = nullptr;

  ImuInitGraph(const ImuInitProblem& problem, const ImuInitResult& start) {
    const int n = static_cast<int>(problem.T_w_b.size());
    // Ids: pose k = 2k, velocity k = 2k+1, then biases and gravity.
    std::vector<VertexPose*> poses;
    for (int k = 0; k < n; ++k) {
      auto pose = std::make_unique<VertexPose>(2 * k, problem.T_w_b[static_cast<size_t>(k)]);
      pose->setFixed(true);
      poses.push_back(graph.addVertex(std::move(pose)));
      velocities.push_back(
          graph.addVertex(std::make_unique<VertexVelocity>(2 * k + 1, start.v_w_b[static_cast<size_t>(k)])));
    }
    gyro_bias = graph.addVertex(std::make_unique<VertexGyroBias>(2 * n, start.bias.b_g));
    acc_bias = graph.addVertex(std::make_unique<VertexAccBias>(2 * n + 1, start.bias.b_a));
    gravity = graph.addVertex(std::make_unique<VertexGravityDir>(2 * n + 2, start.R_w_g));
    if (problem.known_R_w_g) gravity->setFixed(true);
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
    gyro_prior->setMeasurement(problem.gyro_bias_prior_mean);
    gyro_prior->setInformation(problem.gyro_bias_prior_information * Mat3::Identity());
    graph.addEdge(std::move(gyro_prior));
    auto acc_prior = std::make_unique<EdgeAccBiasPrior>();
    acc_prior->setVertex(0, acc_bias);
    acc_prior->setMeasurement(Vec3::Zero());
    acc_prior->setInformation(problem.acc_bias_prior_information * Mat3::Identity());
    graph.addEdge(std::move(acc_prior));
  }
};

}  // namespace

ImuInitResult initializeImu(const ImuInitProblem& problem) {
  ImuInitResult result = linearImuInit(problem);
  if (problem.known_R_w_g) result.R_w_g = *problem.known_R_w_g;
  const int n = static_cast<int>(problem.T_w_b.size());
  ImuInitGraph init(problem, result);
  sparse_opt::Options options;
  options.max_iterations = problem.iterations;
  options.use_schur = false;
  options.num_threads = 1;
  result.summary = init.graph.optimize(options);

  result.R_w_g = init.gravity->estimate();
  result.g_w = imu::gravityFromRotation(result.R_w_g, problem.gravity_m_s2);
  result.bias.b_g = init.gyro_bias->estimate();
  result.bias.b_a = init.acc_bias->estimate();
  for (int k = 0; k < n; ++k) result.v_w_b[static_cast<size_t>(k)] = init.velocities[static_cast<size_t>(k)]->estimate();
  result.acceleration_covariance_w = inertialAccelerationCovariance(problem, result);
  return result;
}

Mat3 inertialAccelerationCovariance(const ImuInitProblem& problem, const ImuInitResult& estimate) {
  const int n = static_cast<int>(problem.T_w_b.size());
  LTLO_ASSERT(n >= 2 && static_cast<int>(estimate.v_w_b.size()) == n,
              "inertialAccelerationCovariance: " << n << " keyframes, " << estimate.v_w_b.size() << " velocities");
  ImuInitGraph init(problem, estimate);
  // Dense normal equations H = sum J^T Omega J over the free vertices (3n + 8 unknowns, at most a
  // few hundred: a dense inverse is cheaper than the sparse machinery and gives the joint blocks).
  std::unordered_map<const sparse_opt::VertexBase*, int> offset;
  int dim = 0;
  for (VertexVelocity* v : init.velocities) {
    offset[v] = dim;
    dim += 3;
  }
  const int gyro_at = dim;
  offset[init.gyro_bias] = gyro_at;
  const int acc_at = gyro_at + 3;
  offset[init.acc_bias] = acc_at;
  const int gravity_at = acc_at + 3;
  offset[init.gravity] = gravity_at;
  dim = gravity_at + 2;
  MatX H = MatX::Zero(dim, dim);
  for (sparse_opt::EdgeBase* edge : init.graph.edges()) {
    if (!edge->linearize()) return Mat3::Constant(std::numeric_limits<double>::infinity());
    for (int a = 0; a < edge->numVertices(); ++a) {
      const auto ia = offset.find(edge->vertex(a));
      if (ia == offset.end()) continue;
      for (int b = 0; b < edge->numVertices(); ++b) {
        const auto ib = offset.find(edge->vertex(b));
        if (ib == offset.end()) continue;
        const int da = edge->vertex(a)->dimension();
        const int db = edge->vertex(b)->dimension();
        MatX block = MatX::Zero(da, db);
        edge->addHessianBlock(a, b, block.data());
        H.block(ia->second, ib->second, da, db) += block;
      }
    }
  }
  // A known gravity (ImuInitProblem::known_R_w_g) is held: no uncertainty in its direction.
  if (problem.known_R_w_g) H.block<2, 2>(gravity_at, gravity_at) += 1e12 * Mat2::Identity();
  const Eigen::LDLT<MatX> ldlt(H);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return Mat3::Constant(std::numeric_limits<double>::infinity());
  // Joint covariance of (b_a, gravity direction): the two trade off (a tilt of gravity reads like a
  // horizontal bias), so only their joint block says how well the world acceleration is known.
  MatX unit = MatX::Zero(dim, 5);
  unit.block<5, 5>(acc_at, 0).setIdentity();
  const MatX columns = ldlt.solve(unit);
  const Eigen::Matrix<double, 5, 5> covariance = columns.block<5, 5>(acc_at, 0);
  // World acceleration of a prediction, a_w = R_w_b (f - b_a) + g_w: its error is
  // -R_w_b db_a + dg_w/dtheta dtheta (body attitude of the newest keyframe; the bias is body-fixed),
  // dg_w/dtheta by central differences on the manifold.
  Eigen::Matrix<double, 3, 5> J;
  J.block<3, 3>(0, 0) = -problem.T_w_b.back().rotationMatrix();
  constexpr double kStep = 1e-6;
  for (int i = 0; i < 2; ++i) {
    Vec2 delta = Vec2::Zero();
    delta[i] = kStep;
    const Vec3 plus = imu::gravityFromRotation(init.gravity->plus(estimate.R_w_g, delta), problem.gravity_m_s2);
    const Vec3 minus = imu::gravityFromRotation(init.gravity->plus(estimate.R_w_g, -delta), problem.gravity_m_s2);
    J.col(3 + i) = (plus - minus) / (2.0 * kStep);
  }
  const Mat3 acceleration = J * covariance * J.transpose();
  return 0.5 * (acceleration + acceleration.transpose());
}

double accelerationSigma(const Mat3& covariance_w) {
  if (!covariance_w.allFinite()) return std::numeric_limits<double>::infinity();
  const Eigen::SelfAdjointEigenSolver<Mat3> eigen(0.5 * (covariance_w + covariance_w.transpose()),
                                                  Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
}

}  // namespace ltlo::optim
