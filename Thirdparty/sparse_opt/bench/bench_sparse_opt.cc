// bench_sparse_opt: sparse_opt against Ceres on the same synthetic problems, same start, same LM
// settings and the same Huber loss. One line per problem ending in ratio=<ours/ceres> (wall time).
//   bench_sparse_opt [--quick] [--threads N] [--iterations N]
#include <ceres/ceres.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include "synthetic_problems.h"

namespace {

using namespace sparse_opt;  // NOLINT: bench program

struct Settings {
  int threads = 2;
  int max_iterations = 30;
  double function_tolerance = 1e-8;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-12;
  double initial_lambda = 1e-4;
};

struct RunResult {
  double time_s = 0.0;
  double cost = 0.0;  // 0.5 sum rho(|whitened residual|^2), Ceres' convention
  int iterations = 0;
  std::string termination;
};

// SE3 stored as [qx qy qz qw tx ty tz]; tangent [phi; rho], left update like sparse_opt::VertexSE3.
// The Jacobians of the cost functions below are written directly against the tangent (first six
// ambient columns), with PlusJacobian = [I6; 0] so Ceres' product gives back the same Jacobian.
class LeftSe3Manifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 7; }
  int TangentSize() const override { return 6; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    const SE3 T = SE3::exp(Eigen::Map<const Vec6>(delta)) * toSe3(x);
    fromSe3(T, x_plus_delta);
    return true;
  }
  bool PlusJacobian(const double*, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, 7, 6, Eigen::RowMajor>> J(jacobian);
    J.setZero();
    J.topRows<6>().setIdentity();
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    const SE3 d = toSe3(y) * toSe3(x).inverse();
    Eigen::Map<Vec6> out(y_minus_x);
    out << so3Log(d.rotation()), d.translation();  // first order, unused by the LM minimiser
    return true;
  }
  bool MinusJacobian(const double*, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> J(jacobian);
    J.setZero();
    J.leftCols<6>().setIdentity();
    return true;
  }
  static SE3 toSe3(const double* x) { return SE3(Quat(x[3], x[0], x[1], x[2]), Vec3(x[4], x[5], x[6])); }
  static void fromSe3(const SE3& T, double* x) {
    x[0] = T.rotation().x();
    x[1] = T.rotation().y();
    x[2] = T.rotation().z();
    x[3] = T.rotation().w();
    x[4] = T.translation().x();
    x[5] = T.translation().y();
    x[6] = T.translation().z();
  }
};

// Both cost functions reuse sparse_opt's own edges for residual and analytic Jacobians, so the
// two solvers see identical numbers; only the solver machinery differs.
class ReprojectionCost final : public ceres::SizedCostFunction<2, 7, 3> {
 public:
  explicit ReprojectionCost(const PinholeIntrinsics& intrinsics, const Vec2& uv) : intrinsics_(intrinsics), uv_(uv) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    VertexSE3 pose(0, LeftSe3Manifold::toSe3(parameters[0]));
    VertexPoint3 point(1, Vec3(parameters[1][0], parameters[1][1], parameters[1][2]));
    EdgeProjectPoint edge(intrinsics_);
    edge.setVertex(0, &pose);
    edge.setVertex(1, &point);
    edge.setMeasurement(uv_);
    edge.computeError();
    Eigen::Map<Vec2> r(residuals);
    r = edge.error();
    if (jacobians != nullptr) {
      edge.linearizeOplus();
      if (jacobians[0] != nullptr) {
        Eigen::Map<Eigen::Matrix<double, 2, 7, Eigen::RowMajor>> J(jacobians[0]);
        J.leftCols<6>() = edge.jacobian<0>();
        J.col(6).setZero();
      }
      if (jacobians[1] != nullptr) {
        Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> J(jacobians[1]);
        J = edge.jacobian<1>();
      }
    }
    return true;
  }

 private:
  PinholeIntrinsics intrinsics_;
  Vec2 uv_;
};

class RelativePoseCost final : public ceres::SizedCostFunction<6, 7, 7> {
 public:
  RelativePoseCost(const SE3& T_i_j, const Mat6& sqrt_information) : T_i_j_(T_i_j), sqrt_information_(sqrt_information) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    VertexSE3 a(0, LeftSe3Manifold::toSe3(parameters[0]));
    VertexSE3 b(1, LeftSe3Manifold::toSe3(parameters[1]));
    EdgeSE3Relative edge;
    edge.setVertex(0, &a);
    edge.setVertex(1, &b);
    edge.setMeasurement(T_i_j_);
    edge.computeError();
    Eigen::Map<Vec6> r(residuals);
    r = sqrt_information_ * edge.error();
    if (jacobians != nullptr) {
      edge.linearizeOplus();
      for (int k = 0; k < 2; ++k) {
        if (jacobians[k] == nullptr) continue;
        Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> J(jacobians[k]);
        J.leftCols<6>() = sqrt_information_ * (k == 0 ? edge.jacobian<0>() : edge.jacobian<1>());
        J.col(6).setZero();
      }
    }
    return true;
  }

 private:
  SE3 T_i_j_;
  Mat6 sqrt_information_;
};

ceres::Solver::Options ceresOptions(const Settings& s, ceres::LinearSolverType type) {
  ceres::Solver::Options options;
  options.linear_solver_type = type;
  options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.initial_trust_region_radius = 1.0 / s.initial_lambda;
  options.jacobi_scaling = false;  // sparse_opt damps with diag(H) directly, as Ceres does without scaling
  options.use_nonmonotonic_steps = false;
  options.max_num_iterations = s.max_iterations;
  options.function_tolerance = s.function_tolerance;
  options.gradient_tolerance = s.gradient_tolerance;
  options.parameter_tolerance = s.parameter_tolerance;
  options.num_threads = s.threads;
  options.logging_type = ceres::SILENT;
  return options;
}

Options oursOptions(const Settings& s) {
  Options options;
  options.max_iterations = s.max_iterations;
  options.function_tolerance = s.function_tolerance;
  options.gradient_tolerance = s.gradient_tolerance;
  options.parameter_tolerance = s.parameter_tolerance;
  options.initial_lambda = s.initial_lambda;
  options.num_threads = s.threads;
  return options;
}

double seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

constexpr double kHuberPx = 2.0;

RunResult runOursBa(const testing::BaProblem& problem, const Settings& settings) {
  Graph graph;
  testing::buildBaGraph(problem, graph, kHuberPx, /*num_fixed=*/2, /*start_at_truth_for_fixed=*/false);
  const auto start = std::chrono::steady_clock::now();
  const Summary summary = graph.optimize(oursOptions(settings));
  return {seconds(start), 0.5 * summary.final_chi2, summary.iterations, summary.termination};
}

RunResult runCeresBa(const testing::BaProblem& problem, const Settings& settings) {
  const int num_cameras = static_cast<int>(problem.T_c_w_init.size());
  std::vector<double> poses(7 * problem.T_c_w_init.size());
  std::vector<double> points(3 * problem.p_w_init.size());
  for (int k = 0; k < num_cameras; ++k) LeftSe3Manifold::fromSe3(problem.T_c_w_init[k], &poses[7 * k]);
  for (size_t j = 0; j < problem.p_w_init.size(); ++j) {
    for (int c = 0; c < 3; ++c) points[3 * j + c] = problem.p_w_init[j][c];
  }
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem ceres_problem(problem_options);
  ceres::HuberLoss huber(kHuberPx);
  LeftSe3Manifold manifold;
  for (const testing::BaObservation& obs : problem.observations) {
    ceres_problem.AddResidualBlock(new ReprojectionCost(problem.intrinsics, obs.uv_px), &huber, &poses[7 * obs.camera],
                                   &points[3 * obs.point]);
  }
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (int k = 0; k < num_cameras; ++k) {
    ceres_problem.SetManifold(&poses[7 * k], &manifold);
    ordering->AddElementToGroup(&poses[7 * k], 1);
  }
  for (size_t j = 0; j < problem.p_w_init.size(); ++j) ordering->AddElementToGroup(&points[3 * j], 0);
  ceres_problem.SetParameterBlockConstant(&poses[0]);
  ceres_problem.SetParameterBlockConstant(&poses[7 * (num_cameras - 1)]);
  ceres::Solver::Options options = ceresOptions(settings, ceres::SPARSE_SCHUR);
  options.linear_solver_ordering = ordering;
  ceres::Solver::Summary summary;
  const auto start = std::chrono::steady_clock::now();
  ceres::Solve(options, &ceres_problem, &summary);
  return {seconds(start), summary.final_cost, static_cast<int>(summary.iterations.size()) - 1,
          ceres::TerminationTypeToString(summary.termination_type)};
}

constexpr double kSigmaRot = 0.01;
constexpr double kSigmaTrans = 0.05;
constexpr double kHuberPoseGraph = 3.0;

RunResult runOursPoseGraph(const testing::PoseGraphProblem& problem, const Settings& settings) {
  Graph graph;
  testing::buildPoseGraph(problem, graph, kSigmaRot, kSigmaTrans, kHuberPoseGraph);
  const auto start = std::chrono::steady_clock::now();
  const Summary summary = graph.optimize(oursOptions(settings));
  return {seconds(start), 0.5 * summary.final_chi2, summary.iterations, summary.termination};
}

RunResult runCeresPoseGraph(const testing::PoseGraphProblem& problem, const Settings& settings) {
  std::vector<double> poses(7 * problem.T_w_init.size());
  for (size_t k = 0; k < problem.T_w_init.size(); ++k) LeftSe3Manifold::fromSe3(problem.T_w_init[k], &poses[7 * k]);
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem ceres_problem(problem_options);
  ceres::HuberLoss huber(kHuberPoseGraph);
  LeftSe3Manifold manifold;
  Mat6 sqrt_information = Mat6::Identity();
  sqrt_information.topLeftCorner<3, 3>() *= 1.0 / kSigmaRot;
  sqrt_information.bottomRightCorner<3, 3>() *= 1.0 / kSigmaTrans;
  for (const testing::RelativePose& r : problem.relatives) {
    ceres_problem.AddResidualBlock(new RelativePoseCost(r.T_i_j, sqrt_information), &huber, &poses[7 * r.i],
                                   &poses[7 * r.j]);
  }
  for (size_t k = 0; k < problem.T_w_init.size(); ++k) ceres_problem.SetManifold(&poses[7 * k], &manifold);
  ceres_problem.SetParameterBlockConstant(&poses[0]);
  const ceres::Solver::Options options = ceresOptions(settings, ceres::SPARSE_NORMAL_CHOLESKY);
  ceres::Solver::Summary summary;
  const auto start = std::chrono::steady_clock::now();
  ceres::Solve(options, &ceres_problem, &summary);
  return {seconds(start), summary.final_cost, static_cast<int>(summary.iterations.size()) - 1,
          ceres::TerminationTypeToString(summary.termination_type)};
}

void printLine(const std::string& name, const RunResult& ours, const RunResult& ceres) {
  const double rel = std::abs(ours.cost - ceres.cost) / std::max(std::abs(ceres.cost), 1e-300);
  std::printf("%-16s ours %.3f s (%d it, cost %.9e, %s) ceres %.3f s (%d it, cost %.9e, %s) cost_rel_diff=%.1e ratio=%.3f\n",
              name.c_str(), ours.time_s, ours.iterations, ours.cost, ours.termination.c_str(), ceres.time_s,
              ceres.iterations, ceres.cost, ceres.termination.c_str(), rel, ours.time_s / ceres.time_s);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  Settings settings;
  bool quick = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--quick") {
      quick = true;
    } else if (arg == "--threads" && i + 1 < argc) {
      settings.threads = std::atoi(argv[++i]);
    } else if (arg == "--iterations" && i + 1 < argc) {
      settings.max_iterations = std::atoi(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: %s [--quick] [--threads N] [--iterations N]\n", argv[0]);
      return 2;
    }
  }
  struct BaSize {
    int cameras, points;
  };
  std::vector<BaSize> sizes = {{10, 1000}, {100, 20000}, {300, 60000}};
  if (quick) sizes = {{10, 1000}, {30, 3000}};
  for (const BaSize& size : sizes) {
    const testing::BaProblem problem =
        testing::makeBa(size.cameras, size.points, /*obs_per_point=*/10, /*noise_px=*/1.0, /*seed=*/42,
                        /*outlier_fraction=*/0.05);
    const RunResult ceres = runCeresBa(problem, settings);
    const RunResult ours = runOursBa(problem, settings);
    printLine("ba_" + std::to_string(size.cameras) + "x" + std::to_string(size.points), ours, ceres);
  }
  const int num_poses = quick ? 200 : 1000;
  const testing::PoseGraphProblem pose_graph =
      testing::makePoseGraph(num_poses, std::max(2, num_poses / 200), /*loop_stride=*/2, kSigmaRot, kSigmaTrans, /*seed=*/42);
  const RunResult ceres = runCeresPoseGraph(pose_graph, settings);
  const RunResult ours = runOursPoseGraph(pose_graph, settings);
  printLine("posegraph_" + std::to_string(num_poses), ours, ceres);
  return 0;
}
