#include "ltlo/optim/bundle_adjust.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <sparse_opt/robust_kernel.h>

#include "ltlo/core/assert.h"
#include "ltlo/optim/inertial_edges.h"
#include "ltlo/optim/vertices.h"
#include "observation_edge.h"

namespace ltlo::optim {

namespace {

using RgbdEdge = EdgeRgbdReprojection<VertexPose>;
using MonoEdge = EdgeMonoReprojection<VertexPose>;

// Vertices of one keyframe (velocity and biases only with an inertial link).
struct KeyFrameVertices {
  VertexPose* pose = nullptr;
  VertexVelocity* velocity = nullptr;
  VertexGyroBias* gyro_bias = nullptr;
  VertexAccBias* acc_bias = nullptr;
};

using ObservationEdge = ReprojectionObservation<RgbdEdge, MonoEdge>;

}  // namespace

LocalBaResult localBundleAdjust(const LocalBaProblem& problem, const LocalBaOptions& options) {
  sparse_opt::Graph graph;
  // Ids: keyframe k (input order) uses 4k .. 4k+3, point m uses 4 K + m.
  const int num_keyframes = static_cast<int>(problem.keyframes.size());
  std::unordered_map<int, int> keyframe_index;
  std::vector<KeyFrameVertices> kf_vertices(problem.keyframes.size());
  for (int k = 0; k < num_keyframes; ++k) {
    const BaKeyFrame& kf = problem.keyframes[static_cast<size_t>(k)];
    LTLO_ASSERT(keyframe_index.emplace(kf.id, k).second, "localBundleAdjust: duplicate keyframe id " << kf.id);
    auto pose = std::make_unique<VertexPose>(4 * k, kf.T_w_b);
    pose->setFixed(kf.fixed);
    kf_vertices[static_cast<size_t>(k)].pose = graph.addVertex(std::move(pose));
  }
  auto index_of = [&](int keyframe_id) {
    const auto it = keyframe_index.find(keyframe_id);
    LTLO_ASSERT(it != keyframe_index.end(), "localBundleAdjust: unknown keyframe id " << keyframe_id);
    return it->second;
  };
  auto ensure_inertial_vertices = [&](int k) {
    KeyFrameVertices& v = kf_vertices[static_cast<size_t>(k)];
    if (v.velocity != nullptr) return;
    const BaKeyFrame& kf = problem.keyframes[static_cast<size_t>(k)];
    auto velocity = std::make_unique<VertexVelocity>(4 * k + 1, kf.v_w_b);
    auto gyro_bias = std::make_unique<VertexGyroBias>(4 * k + 2, kf.bias.b_g);
    auto acc_bias = std::make_unique<VertexAccBias>(4 * k + 3, kf.bias.b_a);
    const bool state_fixed = kf.fixed && !kf.fixed_pose_only;
    velocity->setFixed(state_fixed);
    gyro_bias->setFixed(state_fixed);
    acc_bias->setFixed(state_fixed);
    v.velocity = graph.addVertex(std::move(velocity));
    v.gyro_bias = graph.addVertex(std::move(gyro_bias));
    v.acc_bias = graph.addVertex(std::move(acc_bias));
  };

  // Gravity direction (refinement of the IMU initialisation): one vertex after the points' ids.
  LTLO_ASSERT(!problem.estimate_gravity || !problem.inertial.empty(),
              "localBundleAdjust: the gravity direction needs inertial links");
  const double gravity_m_s2 = problem.g_w.norm();
  VertexGravityDir* gravity = nullptr;
  if (problem.estimate_gravity) {
    const int gravity_id = 4 * num_keyframes + static_cast<int>(problem.points.size());
    gravity = graph.addVertex(
        std::make_unique<VertexGravityDir>(gravity_id, imu::gravityRotationFromDirection(problem.g_w)));
  }
  for (const BaInertialLink& link : problem.inertial) {
    LTLO_ASSERT(link.pim != nullptr, "localBundleAdjust: inertial link without preintegration");
    const int i = index_of(link.keyframe_i);
    const int j = index_of(link.keyframe_j);
    ensure_inertial_vertices(i);
    ensure_inertial_vertices(j);
    const KeyFrameVertices& vi = kf_vertices[static_cast<size_t>(i)];
    const KeyFrameVertices& vj = kf_vertices[static_cast<size_t>(j)];
    if (gravity != nullptr) {
      auto inertial = std::make_unique<EdgeInertialGravity>(link.pim, gravity_m_s2);
      inertial->setVertex(0, vi.pose);
      inertial->setVertex(1, vi.velocity);
      inertial->setVertex(2, vi.gyro_bias);
      inertial->setVertex(3, vi.acc_bias);
      inertial->setVertex(4, vj.pose);
      inertial->setVertex(5, vj.velocity);
      inertial->setVertex(6, gravity);
      inertial->setInformation(problem.inertial_information_scale * inertial->information());
      graph.addEdge(std::move(inertial));
    } else {
      auto inertial = std::make_unique<EdgeInertial>(link.pim, problem.g_w);
      inertial->setVertex(0, vi.pose);
      inertial->setVertex(1, vi.velocity);
      inertial->setVertex(2, vi.gyro_bias);
      inertial->setVertex(3, vi.acc_bias);
      inertial->setVertex(4, vj.pose);
      inertial->setVertex(5, vj.velocity);
      inertial->setInformation(problem.inertial_information_scale * inertial->information());
      graph.addEdge(std::move(inertial));
    }
    auto walk = std::make_unique<EdgeBiasWalk>();
    walk->setVertex(0, vi.gyro_bias);
    walk->setVertex(1, vi.acc_bias);
    walk->setVertex(2, vj.gyro_bias);
    walk->setVertex(3, vj.acc_bias);
    walk->setInformation(problem.inertial_information_scale *
                         biasWalkInformation(link.pim->noise(), std::max(link.pim->dt_s(), 1e-3), problem.lambda_imu));
    graph.addEdge(std::move(walk));
  }

  for (const BaBiasPrior& prior : problem.bias_priors) {
    const KeyFrameVertices& v = kf_vertices[static_cast<size_t>(index_of(prior.keyframe_id))];
    LTLO_ASSERT(v.gyro_bias != nullptr, "localBundleAdjust: bias prior on keyframe " << prior.keyframe_id
                                                                                   << " without an inertial link");
    if (prior.gyro_information > 0.0) {
      auto edge = std::make_unique<EdgeGyroBiasPrior>();
      edge->setVertex(0, v.gyro_bias);
      edge->setMeasurement(prior.mean.b_g);
      edge->setInformation(problem.inertial_information_scale * prior.gyro_information * Mat3::Identity());
      graph.addEdge(std::move(edge));
    }
    if (prior.acc_information > 0.0) {
      auto edge = std::make_unique<EdgeAccBiasPrior>();
      edge->setVertex(0, v.acc_bias);
      edge->setMeasurement(prior.mean.b_a);
      edge->setInformation(problem.inertial_information_scale * prior.acc_information * Mat3::Identity());
      graph.addEdge(std::move(edge));
    }
  }

  std::unordered_map<int, VertexPoint*> point_vertices;
  for (size_t m = 0; m < problem.points.size(); ++m) {
    auto point = std::make_unique<VertexPoint>(4 * num_keyframes + static_cast<int>(m), problem.points[m].p_w);
    point->setMarginalized(true);
    LTLO_ASSERT(point_vertices.emplace(problem.points[m].id, graph.addVertex(std::move(point))).second,
                "localBundleAdjust: duplicate point id " << problem.points[m].id);
  }

  std::vector<ObservationEdge> edges;
  edges.reserve(problem.observations.size());
  for (const BaObservation& obs : problem.observations) {
    const auto point_it = point_vertices.find(obs.point_id);
    LTLO_ASSERT(point_it != point_vertices.end(), "localBundleAdjust: unknown point id " << obs.point_id);
    LTLO_ASSERT(obs.sigma_px > 0.0, "localBundleAdjust: sigma_px = " << obs.sigma_px << ", expected > 0");
    VertexPose* pose = kf_vertices[static_cast<size_t>(index_of(obs.keyframe_id))].pose;
    const double inv_sigma2 = 1.0 / (obs.sigma_px * obs.sigma_px);
    ObservationEdge entry;
    if (obs.depth_m > 0.0) {
      auto edge = std::make_unique<RgbdEdge>(problem.model);
      edge->setVertex(0, pose);
      edge->setVertex(1, point_it->second);
      edge->setMeasurement(problem.model.rgbdObservation(obs.uv, obs.depth_m));
      edge->setObservationInformation(inv_sigma2 * Mat3::Identity());
      edge->setStaticWeight(obs.static_weight);
      edge->setRobustKernel(std::make_unique<sparse_opt::HuberKernel>(std::sqrt(options.chi2_3d)));
      entry.rgbd = graph.addEdge(std::move(edge));
      entry.edge = entry.rgbd;
      entry.threshold = options.chi2_3d;
    } else {
      auto edge = std::make_unique<MonoEdge>(problem.model);
      edge->setVertex(0, pose);
      edge->setVertex(1, point_it->second);
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
  solver_options.max_iterations = options.iterations;
  solver_options.num_threads = options.num_threads;
  solver_options.stop_flag = options.stop_flag;

  LocalBaResult result;
  result.summary = graph.optimize(solver_options);
  result.initial_chi2 = result.summary.initial_chi2;
  const bool stopped = options.stop_flag != nullptr && options.stop_flag->load();
  if (options.reject_outliers && !stopped) {
    for (ObservationEdge& entry : edges) {
      if (!entry.passes()) entry.edge->setLevel(1);
      entry.edge->setRobustKernel(nullptr);
    }
    result.summary = graph.optimize(solver_options);
  }
  result.inliers.reserve(edges.size());
  result.residual_chi2.reserve(edges.size());
  for (const ObservationEdge& entry : edges) {
    bool depth_positive = false;
    const double chi2 = entry.unweightedChi2(&depth_positive);
    result.inliers.push_back(depth_positive && chi2 <= entry.threshold);
    result.residual_chi2.push_back(chi2);
  }

  result.keyframes = problem.keyframes;
  for (size_t k = 0; k < result.keyframes.size(); ++k) {
    const KeyFrameVertices& v = kf_vertices[k];
    result.keyframes[k].T_w_b = v.pose->estimate();
    if (v.velocity != nullptr) {
      result.keyframes[k].v_w_b = v.velocity->estimate();
      result.keyframes[k].bias.b_g = v.gyro_bias->estimate();
      result.keyframes[k].bias.b_a = v.acc_bias->estimate();
    }
  }
  result.points = problem.points;
  for (BaPoint& point : result.points) point.p_w = point_vertices.at(point.id)->estimate();
  result.g_w = gravity != nullptr ? imu::gravityFromRotation(gravity->estimate(), gravity_m_s2) : problem.g_w;
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
