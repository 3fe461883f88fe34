#include "ltlo/system/carried_bridge.h"

#include <cmath>
#include <memory>

#include <Eigen/Cholesky>
#include <sparse_opt/graph.h>

#include "ltlo/core/assert.h"
#include "ltlo/core/log.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/optim/inertial_edges.h"
#include "ltlo/optim/pose_edges.h"
#include "ltlo/optim/vertices.h"

namespace ltlo::system {
namespace {

/// Sample k has IMU data whose preintegration spans the time since sample k - 1, with a usable
/// covariance (positive definite: an inertial edge's information is its inverse) and finite state.
bool linkedToPrevious(const std::vector<CarriedSample>& samples, std::size_t k) {
  if (k == 0 || !samples[k].imu || !samples[k].imu->from_previous || !samples[k - 1].imu) return false;
  const CarriedImu& imu = *samples[k].imu;
  const imu::Preintegrated& pim = *imu.from_previous;
  const double dt_s = samples[k].t_s - samples[k - 1].t_s;
  if (!(dt_s > 0.0 && pim.dt_s() > 0.0 && std::abs(pim.dt_s() - dt_s) <= kMaxBridgeLinkMismatch_s)) return false;
  if (!imu.v_w_b.allFinite() || !imu.g_w.allFinite() || !imu.bias.b_g.allFinite() || !imu.bias.b_a.allFinite() ||
      !pim.deltaP().allFinite() || !pim.deltaV().allFinite() || !pim.deltaR().allFinite()) {
    return false;
  }
  const Mat9 covariance = 0.5 * (pim.covariance() + pim.covariance().transpose());
  return covariance.allFinite() && Eigen::LLT<Mat9>(covariance).info() == Eigen::Success;
}

SE3 bodyPose(const CarriedSample& sample) { return sample.T_w_c * sample.imu->T_b_c.inverse(); }

/// A body pose from a predicted navigation state (SE3 re-orthonormalises the rotation).
SE3 poseOf(const imu::NavState& state) { return SE3(state.R_w_b, state.p_w_b); }

struct NodeVertices {
  optim::VertexPose* pose = nullptr;
  optim::VertexVelocity* velocity = nullptr;
};

}  // namespace

std::optional<CarriedBridgeResult> bridgeCarriedStretch(const std::vector<CarriedSample>& samples,
                                                        std::size_t begin, std::size_t end,
                                                        const CarriedBridgeOptions& options) {
  LTLO_ASSERT(begin >= 1 && begin < end && end < samples.size(),
              "bridgeCarriedStretch: stretch [" << begin << ", " << end << ") of " << samples.size() << " samples");
  const std::size_t start = begin - 1;  // S, the last tracked frame
  const CarriedSample& S = samples[start];
  const CarriedSample& A = samples[end];
  if (!S.imu || !A.imu || S.world != A.world) return std::nullopt;
  for (std::size_t k = begin; k <= end; ++k) {
    if (!linkedToPrevious(samples, k)) return std::nullopt;
  }
  // Margins: tracked frames of the same world, linked, within margin_s of S and of A.
  std::size_t first = start;
  while (first > 0 && !samples[first - 1].carried && samples[first - 1].world == S.world &&
         S.t_s - samples[first - 1].t_s <= options.margin_s && linkedToPrevious(samples, first)) {
    --first;
  }
  std::size_t last = end;
  while (last + 1 < samples.size() && !samples[last + 1].carried && samples[last + 1].world == A.world &&
         samples[last + 1].t_s - A.t_s <= options.margin_s && linkedToPrevious(samples, last + 1)) {
    ++last;
  }
  const std::size_t num_nodes = last - first + 1;
  const Vec3 g_w = S.imu->g_w;
  const imu::ImuBias& bias_S = S.imu->bias;

  // Initial states: the tracked frames at their final poses and tracking's velocities, the
  // carried ones dead-reckoned from S with S's biases (what tracking did, in today's world).
  std::vector<SE3> T_w_b(num_nodes);
  std::vector<Vec3> v_w_b(num_nodes);
  for (std::size_t k = first; k <= last; ++k) {
    const std::size_t n = k - first;
    if (k >= begin && k < end) {
      const imu::NavState predicted = imu::predict(imu::navState(T_w_b[n - 1], v_w_b[n - 1]),
                                                   *samples[k].imu->from_previous, bias_S, g_w);
      T_w_b[n] = poseOf(predicted);
      v_w_b[n] = predicted.v_w_b;
    } else {
      T_w_b[n] = bodyPose(samples[k]);
      v_w_b[n] = samples[k].imu->v_w_b;
    }
  }

  sparse_opt::Graph graph;
  std::vector<NodeVertices> nodes(num_nodes);
  const int num_node_ids = 2 * static_cast<int>(num_nodes);
  for (std::size_t n = 0; n < num_nodes; ++n) {
    auto pose = std::make_unique<optim::VertexPose>(2 * static_cast<int>(n), T_w_b[n]);
    const std::size_t k = first + n;
    pose->setFixed(k == start || k == end);
    nodes[n].pose = graph.addVertex(std::move(pose));
    nodes[n].velocity =
        graph.addVertex(std::make_unique<optim::VertexVelocity>(2 * static_cast<int>(n) + 1, v_w_b[n]));
  }
  optim::VertexGyroBias* gyro_bias =
      graph.addVertex(std::make_unique<optim::VertexGyroBias>(num_node_ids, bias_S.b_g));
  optim::VertexAccBias* acc_bias =
      graph.addVertex(std::make_unique<optim::VertexAccBias>(num_node_ids + 1, bias_S.b_a));

  for (std::size_t n = 1; n < num_nodes; ++n) {
    auto inertial = std::make_unique<optim::EdgeInertial>(samples[first + n].imu->from_previous, g_w);
    inertial->setVertex(0, nodes[n - 1].pose);
    inertial->setVertex(1, nodes[n - 1].velocity);
    inertial->setVertex(2, gyro_bias);
    inertial->setVertex(3, acc_bias);
    inertial->setVertex(4, nodes[n].pose);
    inertial->setVertex(5, nodes[n].velocity);
    graph.addEdge(std::move(inertial));
  }
  // One bias for the window: its prior about S's estimate widens by the random walk over it.
  const double window_s = samples[last].t_s - samples[first].t_s;
  const imu::ImuNoise& noise = S.imu->from_previous ? S.imu->from_previous->noise() : A.imu->from_previous->noise();
  const double gyro_var = options.gyro_bias_sigma_rad_s * options.gyro_bias_sigma_rad_s +
                          noise.gyro_walk_density * noise.gyro_walk_density * window_s;
  const double acc_var = options.acc_bias_sigma_m_s2 * options.acc_bias_sigma_m_s2 +
                         noise.acc_walk_density * noise.acc_walk_density * window_s;
  if (gyro_var > 0.0) {
    auto prior = std::make_unique<optim::EdgeGyroBiasPrior>();
    prior->setVertex(0, gyro_bias);
    prior->setMeasurement(bias_S.b_g);
    prior->setInformation(Mat3::Identity() / gyro_var);
    graph.addEdge(std::move(prior));
  } else {
    gyro_bias->setFixed(true);
  }
  if (acc_var > 0.0) {
    auto prior = std::make_unique<optim::EdgeAccBiasPrior>();
    prior->setVertex(0, acc_bias);
    prior->setMeasurement(bias_S.b_a);
    prior->setInformation(Mat3::Identity() / acc_var);
    graph.addEdge(std::move(prior));
  } else {
    acc_bias->setFixed(true);
  }
  if (options.velocity_sigma_m_s > 0.0) {
    auto prior = std::make_unique<optim::EdgeVelocityPrior>();
    prior->setVertex(0, nodes[start - first].velocity);
    prior->setMeasurement(S.imu->v_w_b);
    prior->setInformation(Mat3::Identity() / (options.velocity_sigma_m_s * options.velocity_sigma_m_s));
    graph.addEdge(std::move(prior));
  }
  Mat6 margin_information = Mat6::Zero();
  margin_information.topLeftCorner<3, 3>() =
      Mat3::Identity() / (options.margin_rotation_sigma_rad * options.margin_rotation_sigma_rad);
  margin_information.bottomRightCorner<3, 3>() =
      Mat3::Identity() / (options.margin_position_sigma_m * options.margin_position_sigma_m);
  for (std::size_t k = first; k <= last; ++k) {
    if (k >= start && k <= end) continue;
    auto prior = std::make_unique<optim::EdgePosePrior>();
    prior->setVertex(0, nodes[k - first].pose);
    prior->setMeasurement(T_w_b[k - first]);
    prior->setInformation(margin_information);
    graph.addEdge(std::move(prior));
  }

  sparse_opt::Options solver;
  solver.max_iterations = options.max_iterations;
  solver.num_threads = 1;
  const sparse_opt::Summary summary = graph.optimize(solver);

  CarriedBridgeResult result;
  result.bias.b_g = gyro_bias->estimate();
  result.bias.b_a = acc_bias->estimate();
  result.margin_before = static_cast<int>(start - first);
  result.margin_after = static_cast<int>(last - end);
  result.initial_chi2 = summary.initial_chi2;
  result.final_chi2 = summary.final_chi2;
  result.iterations = summary.iterations;
  if (!std::isfinite(summary.final_chi2) || !result.bias.b_g.allFinite() || !result.bias.b_a.allFinite()) {
    return std::nullopt;
  }
  result.T_w_c.reserve(end - begin);
  for (std::size_t k = begin; k < end; ++k) {
    const SE3 T_w_c = nodes[k - first].pose->estimate() * samples[k].imu->T_b_c;
    if (!T_w_c.translation().allFinite() || !T_w_c.quaternion().coeffs().allFinite()) return std::nullopt;
    result.T_w_c.push_back(T_w_c);
  }
  return result;
}

}  // namespace ltlo::system
