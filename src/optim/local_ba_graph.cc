#include "ltlo/optim/local_ba_graph.h"

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
using ObservationEdge = ReprojectionObservation<RgbdEdge, MonoEdge>;

// Vertices of one keyframe (velocity and biases only with an inertial link).
struct KeyFrameVertices {
  VertexPose* pose = nullptr;
  VertexVelocity* velocity = nullptr;
  VertexGyroBias* gyro_bias = nullptr;
  VertexAccBias* acc_bias = nullptr;
};

/// An inertial edge's vertices 0-5: pose, velocity, gyro and accelerometer bias of keyframe i,
/// pose and velocity of keyframe j (EdgeInertial and EdgeInertialGravity alike).
template <typename InertialEdge>
void connectKeyFrameStates(InertialEdge& edge, const KeyFrameVertices& vi, const KeyFrameVertices& vj) {
  edge.setVertex(0, vi.pose);
  edge.setVertex(1, vi.velocity);
  edge.setVertex(2, vi.gyro_bias);
  edge.setVertex(3, vi.acc_bias);
  edge.setVertex(4, vj.pose);
  edge.setVertex(5, vj.velocity);
}

}  // namespace

struct LocalBaGraph::Impl {
  LocalBaProblem problem;  // the inputs (ids, initial estimates), copied once
  LocalBaOptions options;
  sparse_opt::Graph graph;
  std::vector<KeyFrameVertices> keyframes;
  std::unordered_map<int, int> keyframe_index;  // keyframe id -> input order
  VertexGravityDir* gravity = nullptr;  // with problem.estimate_gravity
  double gravity_m_s2 = 0.0;
  std::vector<VertexPoint*> points;
  std::unordered_map<int, std::size_t> point_index;  // point id -> input order
  std::vector<ObservationEdge> edges;       // problem order
  std::vector<std::size_t> edge_point;      // point index of each observation
  std::vector<bool> has_depth;              // RGB-D edge (3-D) or monocular (2-D)
  std::vector<std::vector<std::size_t>> point_edges;  // observations of each point

  /// A point needs a depth edge or two 2-D edges in the system, else its block is singular: the
  /// edges of a point without them leave the system too (it keeps its position). Returns the
  /// number of active observations.
  int holdUnderConstrainedPoints() {
    int active = 0;
    for (const std::vector<std::size_t>& observations : point_edges) {
      int depth_edges = 0, mono_edges = 0;
      for (const std::size_t o : observations) {
        if (edges[o].edge->level() != 0) continue;
        (has_depth[o] ? depth_edges : mono_edges)++;
      }
      if (depth_edges == 0 && mono_edges < 2) {
        for (const std::size_t o : observations) edges[o].edge->setLevel(1);
      } else {
        active += depth_edges + mono_edges;
      }
    }
    return active;
  }

  // Ids: keyframe k (input order) uses 4k .. 4k+3, point m uses 4 K + m.
  void addPoseVertices();
  int indexOf(int keyframe_id) const;
  void ensureInertialVertices(int k);
  // Gravity direction (refinement of the IMU initialisation): one vertex after the points' ids.
  void addGravityVertex();
  void addInertialLink(const BaInertialLink& link);
  void addInertialEdge(const BaInertialLink& link, const KeyFrameVertices& vi, const KeyFrameVertices& vj);
  // Bias random walk between consecutive keyframes, Eq. 58.
  void addBiasWalkEdge(const BaInertialLink& link, const KeyFrameVertices& vi, const KeyFrameVertices& vj);
  void addBiasPriors();
  void addPointVertices();
  void addObservation(const BaObservation& obs);
};

void LocalBaGraph::Impl::addPoseVertices() {
  const int num_keyframes = static_cast<int>(problem.keyframes.size());
  keyframes.resize(problem.keyframes.size());
  for (int k = 0; k < num_keyframes; ++k) {
    const BaKeyFrame& kf = problem.keyframes[static_cast<std::size_t>(k)];
    LTLO_ASSERT(keyframe_index.emplace(kf.id, k).second, "localBundleAdjust: duplicate keyframe id " << kf.id);
    auto pose = std::make_unique<VertexPose>(4 * k, kf.T_w_b);
    pose->setFixed(kf.fixed);
    keyframes[static_cast<std::size_t>(k)].pose = graph.addVertex(std::move(pose));
  }
}

int LocalBaGraph::Impl::indexOf(int keyframe_id) const {
  const auto it = keyframe_index.find(keyframe_id);
  LTLO_ASSERT(it != keyframe_index.end(), "localBundleAdjust: unknown keyframe id " << keyframe_id);
  return it->second;
}

void LocalBaGraph::Impl::ensureInertialVertices(int k) {
  KeyFrameVertices& v = keyframes[static_cast<std::size_t>(k)];
  if (v.velocity != nullptr) return;
  const BaKeyFrame& kf = problem.keyframes[static_cast<std::size_t>(k)];
  auto velocity = std::make_unique<VertexVelocity>(4 * k + 1, kf.v_w_b);
  auto gyro_bias = std::make_unique<VertexGyroBias>(4 * k + 2, kf.bias.b_g);
  auto acc_bias = std::make_unique<VertexAccBias>(4 * k + 3, kf.bias.b_a);
  const bool state_fixed = kf.fixed && !kf.fixed_pose_only;
  velocity->setFixed(state_fixed && !kf.velocity_free);
  gyro_bias->setFixed(state_fixed);
  acc_bias->setFixed(state_fixed);
  v.velocity = graph.addVertex(std::move(velocity));
  v.gyro_bias = graph.addVertex(std::move(gyro_bias));
  v.acc_bias = graph.addVertex(std::move(acc_bias));
  if (state_fixed && kf.velocity_free && kf.velocity_prior_sigma_m_s > 0.0) {
    auto prior = std::make_unique<EdgeVelocityPrior>();
    prior->setVertex(0, v.velocity);
    prior->setMeasurement(kf.velocity_prior);
    prior->setInformation(Mat3::Identity() / (kf.velocity_prior_sigma_m_s * kf.velocity_prior_sigma_m_s));
    graph.addEdge(std::move(prior));
  }
}

void LocalBaGraph::Impl::addGravityVertex() {
  LTLO_ASSERT(!problem.estimate_gravity || !problem.inertial.empty(),
              "localBundleAdjust: the gravity direction needs inertial links");
  gravity_m_s2 = problem.g_w.norm();
  if (problem.estimate_gravity) {
    const int num_keyframes = static_cast<int>(problem.keyframes.size());
    const int gravity_id = 4 * num_keyframes + static_cast<int>(problem.points.size());
    gravity = graph.addVertex(
        std::make_unique<VertexGravityDir>(gravity_id, imu::gravityRotationFromDirection(problem.g_w)));
  }
}

void LocalBaGraph::Impl::addInertialLink(const BaInertialLink& link) {
  LTLO_ASSERT(link.pim != nullptr, "localBundleAdjust: inertial link without preintegration");
  const int i = indexOf(link.keyframe_i);
  const int j = indexOf(link.keyframe_j);
  ensureInertialVertices(i);
  ensureInertialVertices(j);
  const KeyFrameVertices& vi = keyframes[static_cast<std::size_t>(i)];
  const KeyFrameVertices& vj = keyframes[static_cast<std::size_t>(j)];
  addInertialEdge(link, vi, vj);
  addBiasWalkEdge(link, vi, vj);
}

void LocalBaGraph::Impl::addInertialEdge(const BaInertialLink& link, const KeyFrameVertices& vi,
                                         const KeyFrameVertices& vj) {
  if (gravity != nullptr) {
    auto inertial = std::make_unique<EdgeInertialGravity>(link.pim, gravity_m_s2);
    connectKeyFrameStates(*inertial, vi, vj);
    inertial->setVertex(6, gravity);
    inertial->setInformation(problem.inertial_information_scale * inertial->information());
    graph.addEdge(std::move(inertial));
  } else {
    auto inertial = std::make_unique<EdgeInertial>(link.pim, problem.g_w);
    connectKeyFrameStates(*inertial, vi, vj);
    inertial->setInformation(problem.inertial_information_scale * inertial->information());
    graph.addEdge(std::move(inertial));
  }
}

void LocalBaGraph::Impl::addBiasWalkEdge(const BaInertialLink& link, const KeyFrameVertices& vi,
                                         const KeyFrameVertices& vj) {
  auto walk = std::make_unique<EdgeBiasWalk>();
  walk->setVertex(0, vi.gyro_bias);
  walk->setVertex(1, vi.acc_bias);
  walk->setVertex(2, vj.gyro_bias);
  walk->setVertex(3, vj.acc_bias);
  const double walk_s = std::max(link.pim->dt_s(), imu::kMinBiasWalkInterval_s);
  Mat6 walk_information = biasWalkInformation(link.pim->noise(), walk_s, problem.lambda_imu);
  if (problem.held_acc_bias_sigma_m_s2 > 0.0 && problem.lambda_imu > 0.0 &&
      vi.acc_bias->fixed() != vj.acc_bias->fixed()) {
    // One end held at an estimate known to held_acc_bias_sigma: its error adds to the walk's
    // (covariance of the difference b_j - b_i; Eq. 58's weight applies to the walk part).
    Mat6 covariance = link.pim->noise().biasWalkCovariance(walk_s) / problem.lambda_imu;
    covariance.bottomRightCorner<3, 3>() +=
        Mat3::Identity() * (problem.held_acc_bias_sigma_m_s2 * problem.held_acc_bias_sigma_m_s2);
    walk_information = covariance.ldlt().solve(Mat6::Identity());
    walk_information = 0.5 * (walk_information + walk_information.transpose());
  }
  walk->setInformation(problem.inertial_information_scale * walk_information);
  graph.addEdge(std::move(walk));
}

void LocalBaGraph::Impl::addBiasPriors() {
  for (const BaBiasPrior& prior : problem.bias_priors) {
    const KeyFrameVertices& v = keyframes[static_cast<std::size_t>(indexOf(prior.keyframe_id))];
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
}

void LocalBaGraph::Impl::addPointVertices() {
  const int num_keyframes = static_cast<int>(problem.keyframes.size());
  for (std::size_t m = 0; m < problem.points.size(); ++m) {
    auto point = std::make_unique<VertexPoint>(4 * num_keyframes + static_cast<int>(m), problem.points[m].p_w);
    point->setMarginalized(true);
    LTLO_ASSERT(point_index.emplace(problem.points[m].id, m).second,
                "localBundleAdjust: duplicate point id " << problem.points[m].id);
    points.push_back(graph.addVertex(std::move(point)));
  }
  point_edges.resize(problem.points.size());
}

void LocalBaGraph::Impl::addObservation(const BaObservation& obs) {
  const auto point_it = point_index.find(obs.point_id);
  LTLO_ASSERT(point_it != point_index.end(), "localBundleAdjust: unknown point id " << obs.point_id);
  LTLO_ASSERT(obs.sigma_px > 0.0, "localBundleAdjust: sigma_px = " << obs.sigma_px << ", expected > 0");
  VertexPose* pose = keyframes[static_cast<std::size_t>(indexOf(obs.keyframe_id))].pose;
  VertexPoint* point = points[point_it->second];
  const double inv_sigma2 = 1.0 / (obs.sigma_px * obs.sigma_px);
  ObservationEdge entry;
  if (obs.depth_m > 0.0) {
    auto edge = std::make_unique<RgbdEdge>(problem.model);
    edge->setVertex(0, pose);
    edge->setVertex(1, point);
    edge->setMeasurement(problem.model.rgbdObservation(obs.uv, obs.depth_m));
    edge->setObservationInformation(inv_sigma2 * Mat3::Identity());
    edge->setRobustKernel(std::make_unique<sparse_opt::HuberKernel>(std::sqrt(options.chi2_3d)));
    entry.rgbd = graph.addEdge(std::move(edge));
    entry.edge = entry.rgbd;
    entry.threshold = options.chi2_3d;
  } else {
    auto edge = std::make_unique<MonoEdge>(problem.model);
    edge->setVertex(0, pose);
    edge->setVertex(1, point);
    edge->setMeasurement(obs.uv);
    edge->setObservationInformation(inv_sigma2 * Mat2::Identity());
    edge->setRobustKernel(std::make_unique<sparse_opt::HuberKernel>(std::sqrt(options.chi2_2d)));
    entry.mono = graph.addEdge(std::move(edge));
    entry.edge = entry.mono;
    entry.threshold = options.chi2_2d;
  }
  point_edges[point_it->second].push_back(edges.size());
  edges.push_back(entry);
  edge_point.push_back(point_it->second);
  has_depth.push_back(obs.depth_m > 0.0);
}

LocalBaGraph::LocalBaGraph(const LocalBaProblem& problem, const LocalBaOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  d.problem = problem;
  d.options = options;
  d.addPoseVertices();
  d.addGravityVertex();
  for (const BaInertialLink& link : d.problem.inertial) d.addInertialLink(link);
  d.addBiasPriors();
  d.addPointVertices();
  d.edges.reserve(problem.observations.size());
  for (const BaObservation& obs : d.problem.observations) d.addObservation(obs);
  std::vector<double> weights;
  weights.reserve(problem.observations.size());
  for (const BaObservation& obs : problem.observations) weights.push_back(obs.static_weight);
  setStaticWeights(weights);
}

LocalBaGraph::~LocalBaGraph() = default;

std::size_t LocalBaGraph::numObservations() const { return impl_->edges.size(); }

int LocalBaGraph::setStaticWeights(const std::vector<double>& weights) {
  Impl& d = *impl_;
  LTLO_ASSERT(weights.size() == d.edges.size(), weights.size() << " static weights for " << d.edges.size()
                                                                << " observations");
  for (std::size_t o = 0; o < d.edges.size(); ++o) {
    const double w = weights[o];
    LTLO_ASSERT(std::isfinite(w) && w >= 0.0, "static weight " << w << " of observation " << o);
    if (d.edges[o].rgbd != nullptr) {
      d.edges[o].rgbd->setStaticWeight(w);
    } else {
      d.edges[o].mono->setStaticWeight(w);
    }
    d.edges[o].edge->setLevel(w >= kMinActiveStaticWeight ? 0 : 1);
  }
  return d.holdUnderConstrainedPoints();
}

sparse_opt::Summary LocalBaGraph::optimize(int iterations) {
  sparse_opt::Options solver_options;
  solver_options.max_iterations = iterations;
  solver_options.num_threads = impl_->options.num_threads;
  solver_options.stop_flag = impl_->options.stop_flag;
  return impl_->graph.optimize(solver_options);
}

void LocalBaGraph::residuals(const std::vector<bool>& wanted, std::vector<double>* r_sq,
                             std::vector<bool>* in_front) const {
  const Impl& d = *impl_;
  LTLO_ASSERT(wanted.size() == d.edges.size(), "LocalBaGraph::residuals: " << wanted.size() << " flags for "
                                                                            << d.edges.size() << " observations");
  if (r_sq != nullptr) r_sq->assign(d.edges.size(), 0.0);
  if (in_front != nullptr) in_front->assign(d.edges.size(), false);
  for (std::size_t o = 0; o < d.edges.size(); ++o) {
    if (!wanted[o]) continue;
    bool depth_positive = false;
    const double chi2 = d.edges[o].unweightedChi2(&depth_positive);
    if (r_sq != nullptr) (*r_sq)[o] = chi2;
    if (in_front != nullptr) (*in_front)[o] = depth_positive;
  }
}

int LocalBaGraph::rejectOutliers() {
  Impl& d = *impl_;
  for (ObservationEdge& entry : d.edges) {
    if (entry.edge->level() == 0 && !entry.passes()) entry.edge->setLevel(1);
    entry.edge->setRobustKernel(nullptr);
  }
  return d.holdUnderConstrainedPoints();
}

SE3 LocalBaGraph::T_w_b(std::size_t keyframe_index) const { return impl_->keyframes.at(keyframe_index).pose->estimate(); }

Vec3 LocalBaGraph::p_w(std::size_t point_index) const { return impl_->points.at(point_index)->estimate(); }

LocalBaResult LocalBaGraph::result(const sparse_opt::Summary& summary) const {
  const Impl& d = *impl_;
  LocalBaResult result;
  result.summary = summary;
  result.inliers.reserve(d.edges.size());
  result.residual_chi2.reserve(d.edges.size());
  for (const ObservationEdge& entry : d.edges) {
    bool depth_positive = false;
    const double chi2 = entry.unweightedChi2(&depth_positive);
    result.inliers.push_back(depth_positive && chi2 <= entry.threshold);
    result.residual_chi2.push_back(chi2);
  }
  result.keyframes = d.problem.keyframes;
  for (std::size_t k = 0; k < result.keyframes.size(); ++k) {
    const KeyFrameVertices& v = d.keyframes[k];
    result.keyframes[k].T_w_b = v.pose->estimate();
    if (v.velocity != nullptr) {
      result.keyframes[k].v_w_b = v.velocity->estimate();
      result.keyframes[k].bias.b_g = v.gyro_bias->estimate();
      result.keyframes[k].bias.b_a = v.acc_bias->estimate();
    }
  }
  result.points = d.problem.points;
  for (std::size_t m = 0; m < result.points.size(); ++m) result.points[m].p_w = d.points[m]->estimate();
  result.g_w = d.gravity != nullptr ? imu::gravityFromRotation(d.gravity->estimate(), d.gravity_m_s2) : d.problem.g_w;
  return result;
}

}  // namespace ltlo::optim
