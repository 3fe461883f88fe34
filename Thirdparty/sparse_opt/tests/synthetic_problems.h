// Fixed-seed synthetic bundle adjustment and pose-graph problems shared by the tests and the
// benchmark (header-only, test/bench code only).
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "sparse_opt/graph.h"
#include "sparse_opt/manifold.h"
#include "sparse_opt/types.h"

namespace sparse_opt::testing {

struct BaObservation {
  int camera;
  int point;
  Vec2 uv_px;
};

struct BaProblem {
  PinholeIntrinsics intrinsics;
  std::vector<SE3> T_c_w_true, T_c_w_init;
  std::vector<Vec3> p_w_true, p_w_init;
  std::vector<BaObservation> observations;
};

inline Vec3 randomVec3(std::mt19937& rng, double sigma) {
  std::normal_distribution<double> n(0.0, sigma);
  return Vec3(n(rng), n(rng), n(rng));
}

inline SE3 perturb(const SE3& T, std::mt19937& rng, double sigma_rot_rad, double sigma_trans_m) {
  Vec6 xi;
  xi << randomVec3(rng, sigma_rot_rad), randomVec3(rng, sigma_trans_m);
  return SE3::exp(xi) * T;
}

/// Cameras along a gently curving path looking forward at points 4..10 m ahead; each point is
/// seen by about obs_per_point consecutive cameras. outlier_fraction of the observations get a
/// gross error of 20..50 px.
inline BaProblem makeBa(int num_cameras, int num_points, int obs_per_point, double noise_px, unsigned seed,
                        double outlier_fraction = 0.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::normal_distribution<double> pixel_noise(0.0, noise_px);
  BaProblem problem;
  problem.intrinsics = {500.0, 500.0, 320.0, 240.0};
  const double spacing_m = 0.3;
  for (int k = 0; k < num_cameras; ++k) {
    const double s = k * spacing_m;
    const Vec3 t_w_c(s, 0.3 * std::sin(0.05 * k), 0.1 * std::cos(0.07 * k));
    const Quat q_w_c = so3Exp(Vec3(0.02 * std::sin(0.3 * k), 0.05 * std::sin(0.1 * k), 0.01 * k));
    problem.T_c_w_true.push_back(SE3(q_w_c, t_w_c).inverse());
  }
  const int window = std::min(obs_per_point, num_cameras);
  for (int j = 0; j < num_points; ++j) {
    const int first = static_cast<int>(uni(rng) * (num_cameras - window + 1));
    const int center = std::min(num_cameras - 1, first + window / 2);
    const SE3 T_w_c = problem.T_c_w_true[center].inverse();
    const Vec3 p_c(uni(rng) * 6.0 - 3.0, uni(rng) * 4.0 - 2.0, 4.0 + uni(rng) * 6.0);
    const Vec3 p_w = T_w_c * p_c;
    problem.p_w_true.push_back(p_w);
    for (int k = first; k < first + window; ++k) {
      const Vec3 q = problem.T_c_w_true[k] * p_w;
      Vec2 uv(problem.intrinsics.fx * q.x() / q.z() + problem.intrinsics.cx,
              problem.intrinsics.fy * q.y() / q.z() + problem.intrinsics.cy);
      uv += Vec2(pixel_noise(rng), pixel_noise(rng));
      if (uni(rng) < outlier_fraction) {
        const double angle = uni(rng) * 2.0 * M_PI;
        uv += (20.0 + 30.0 * uni(rng)) * Vec2(std::cos(angle), std::sin(angle));
      }
      problem.observations.push_back({k, j, uv});
    }
  }
  for (const SE3& T : problem.T_c_w_true) problem.T_c_w_init.push_back(perturb(T, rng, 0.01, 0.05));
  for (const Vec3& p : problem.p_w_true) problem.p_w_init.push_back(p + randomVec3(rng, 0.1));
  return problem;
}

/// Ids: cameras 0..C-1, points C..C+P-1. Fixed (gauge and scale): camera 0 if num_fixed >= 1, and
/// with num_fixed >= 2 also the last camera and cameras 1..num_fixed-2.
inline void buildBaGraph(const BaProblem& problem, Graph& graph, double huber_delta_px, int num_fixed = 2,
                         bool start_at_truth_for_fixed = true) {
  const int num_cameras = static_cast<int>(problem.T_c_w_init.size());
  for (int k = 0; k < num_cameras; ++k) {
    const bool fixed = (num_fixed >= 1 && k == 0) || (num_fixed >= 2 && (k == num_cameras - 1 || k < num_fixed - 1));
    auto v = std::make_unique<VertexSE3>(
        k, fixed && start_at_truth_for_fixed ? problem.T_c_w_true[k] : problem.T_c_w_init[k]);
    v->setFixed(fixed);
    graph.addVertex(std::move(v));
  }
  for (size_t j = 0; j < problem.p_w_init.size(); ++j) {
    auto v = std::make_unique<VertexPoint3>(num_cameras + static_cast<int>(j), problem.p_w_init[j]);
    v->setMarginalized(true);
    graph.addVertex(std::move(v));
  }
  for (const BaObservation& obs : problem.observations) {
    auto e = std::make_unique<EdgeProjectPoint>(problem.intrinsics);
    e->setVertex(0, graph.vertex(obs.camera));
    e->setVertex(1, graph.vertex(num_cameras + obs.point));
    e->setMeasurement(obs.uv_px);
    if (huber_delta_px > 0.0) e->setRobustKernel(std::make_unique<HuberKernel>(huber_delta_px));
    graph.addEdge(std::move(e));
  }
}

struct RelativePose {
  int i;
  int j;
  SE3 T_i_j;
  bool outlier;
};

struct PoseGraphProblem {
  std::vector<SE3> T_w_true, T_w_init;
  std::vector<RelativePose> relatives;
};

/// Poses on a helix of num_turns turns; odometry between consecutive poses, loop closures between
/// poses one turn apart (every loop_stride-th pose). The start is the composed noisy odometry.
/// outlier_fraction of the loop closures are replaced by random wrong relative poses.
inline PoseGraphProblem makePoseGraph(int num_poses, int num_turns, int loop_stride, double sigma_rot_rad,
                                      double sigma_trans_m, unsigned seed, double outlier_fraction = 0.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  PoseGraphProblem problem;
  const int per_turn = num_poses / num_turns;
  const double radius_m = 10.0;
  for (int k = 0; k < num_poses; ++k) {
    const double angle = 2.0 * M_PI * k / per_turn;
    const Vec3 t(radius_m * std::cos(angle), radius_m * std::sin(angle), 0.5 * k / per_turn);
    problem.T_w_true.push_back(SE3(so3Exp(Vec3(0.0, 0.0, angle + M_PI / 2)) * so3Exp(Vec3(0.05 * std::sin(angle), 0, 0)), t));
  }
  auto noisyRelative = [&](int i, int j) {
    const SE3 T_i_j = problem.T_w_true[i].inverse() * problem.T_w_true[j];
    return perturb(T_i_j, rng, sigma_rot_rad, sigma_trans_m);
  };
  for (int k = 0; k + 1 < num_poses; ++k) problem.relatives.push_back({k, k + 1, noisyRelative(k, k + 1), false});
  for (int k = 0; k + per_turn < num_poses; k += loop_stride) {
    RelativePose loop{k, k + per_turn, noisyRelative(k, k + per_turn), false};
    if (uni(rng) < outlier_fraction) {
      loop.T_i_j = perturb(loop.T_i_j, rng, 0.5, 3.0);
      loop.outlier = true;
    }
    problem.relatives.push_back(loop);
  }
  problem.T_w_init.push_back(problem.T_w_true[0]);
  for (int k = 0; k + 1 < num_poses; ++k) {
    problem.T_w_init.push_back(problem.T_w_init.back() * problem.relatives[static_cast<size_t>(k)].T_i_j);
  }
  return problem;
}

/// Ids 0..N-1; pose 0 fixed. Information: 1/sigma^2 on each block.
inline void buildPoseGraph(const PoseGraphProblem& problem, Graph& graph, double sigma_rot_rad, double sigma_trans_m,
                           double huber_delta = 0.0) {
  for (size_t k = 0; k < problem.T_w_init.size(); ++k) {
    auto v = std::make_unique<VertexSE3>(static_cast<int>(k), problem.T_w_init[k]);
    v->setFixed(k == 0);
    graph.addVertex(std::move(v));
  }
  Mat6 info = Mat6::Identity();
  info.topLeftCorner<3, 3>() *= 1.0 / (sigma_rot_rad * sigma_rot_rad);
  info.bottomRightCorner<3, 3>() *= 1.0 / (sigma_trans_m * sigma_trans_m);
  for (const RelativePose& r : problem.relatives) {
    auto e = std::make_unique<EdgeSE3Relative>();
    e->setVertex(0, graph.vertex(r.i));
    e->setVertex(1, graph.vertex(r.j));
    e->setMeasurement(r.T_i_j);
    e->setInformation(info);
    if (huber_delta > 0.0) e->setRobustKernel(std::make_unique<HuberKernel>(huber_delta));
    graph.addEdge(std::move(e));
  }
}

inline double rotationDistanceRad(const SE3& a, const SE3& b) { return so3Log(a.rotation().conjugate() * b.rotation()).norm(); }

}  // namespace sparse_opt::testing
