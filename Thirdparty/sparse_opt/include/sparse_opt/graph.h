// The optimisation graph: owns vertices and edges and runs Levenberg-Marquardt or Gauss-Newton
// on the block-sparse normal equations (Schur complement on marginalised vertices, CHOLMOD or
// dense Cholesky on the reduced system).
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "sparse_opt/edge.h"
#include "sparse_opt/vertex.h"

namespace sparse_opt {

namespace internal {
class Solver;
}

enum class Algorithm { kLevenbergMarquardt, kGaussNewton };
enum class LinearSolverType {
  kAuto,     ///< dense when the reduced system has <= dense_max_dimension unknowns, else CHOLMOD
  kCholmod,  ///< SuiteSparse CHOLMOD (supernodal or simplicial, CHOLMOD decides)
  kDense,    ///< Eigen dense Cholesky
};

struct Options {
  Algorithm algorithm = Algorithm::kLevenbergMarquardt;
  LinearSolverType linear_solver = LinearSolverType::kAuto;
  bool use_schur = true;            ///< eliminate marginalised vertices by the Schur complement
  int dense_max_dimension = 60;     ///< kAuto threshold on the reduced system size
  int max_iterations = 20;          ///< counts accepted and rejected LM steps
  double initial_lambda = 1e-4;     ///< LM damping: (H + lambda clamp(diag H, 1e-6, 1e32)) dx = b
  double function_tolerance = 1e-6; ///< stop when an accepted step reduces chi2 by less than this fraction
  double gradient_tolerance = 1e-10;///< stop when max |J^T W e| falls below
  double parameter_tolerance = 1e-8;///< stop when |dx| falls below
  int num_threads = 2;              ///< linearisation and Schur threads (1 or 2); results do not depend on it
  int level = 0;                    ///< only edges with this level are optimised
  const std::atomic<bool>* stop_flag = nullptr;  ///< checked between iterations, may be null
};

struct IterationStats {
  int iteration = 0;
  double chi2 = 0.0;        ///< robust chi2 after this iteration (of the accepted estimate)
  double lambda = 0.0;      ///< damping used for this iteration's step
  bool accepted = false;
  double time_s = 0.0;      ///< wall time since optimize() started
};

/// Wall time per stage, summed over the iterations of one optimize() call.
struct StageTimes {
  double setup_s = 0.0;      ///< vertex ordering, block structure, CHOLMOD symbolic analysis
  double linearize_s = 0.0;  ///< residuals, Jacobians and block accumulation
  double schur_s = 0.0;      ///< damping, Schur complement and back-substitution
  double factorize_s = 0.0;  ///< Cholesky factorisation and solve of the reduced system
  double evaluate_s = 0.0;   ///< chi2 of trial points
};

struct Summary {
  bool converged = false;   ///< a tolerance was met (not the iteration cap or the stop flag)
  std::string termination;  ///< why it stopped, readable
  int iterations = 0;
  int accepted_iterations = 0;
  double initial_chi2 = 0.0;  ///< robust chi2 (sum of rho(e^T Omega e)); Ceres' cost is half of it
  double final_chi2 = 0.0;
  double total_time_s = 0.0;
  bool used_schur = false;
  bool used_cholmod = false;
  bool reused_symbolic = false;  ///< CHOLMOD symbolic analysis reused from a previous call
  /// The block structure reused from the previous call: the same edges (in the same order) on the
  /// same vertices, none of them fixed, freed or marginalised since (only the estimates and the
  /// edges' weights changed, as between a robust BA's rounds)
  bool reused_structure = false;
  int reduced_dimension = 0;
  std::vector<IterationStats> history;
  StageTimes stage_times;
};

/// Owns vertices and edges (unique ownership; raw pointers returned are valid until removal).
/// Not thread-safe; optimize() uses up to Options::num_threads threads internally.
class Graph {
 public:
  Graph();
  ~Graph();
  Graph(const Graph&) = delete;
  Graph& operator=(const Graph&) = delete;

  /// Adds a vertex; throws Error on a duplicate id or null.
  template <class V>
  V* addVertex(std::unique_ptr<V> vertex) {
    V* raw = vertex.get();
    addVertexImpl(std::unique_ptr<VertexBase>(std::move(vertex)));
    return raw;
  }
  /// Adds an edge and assigns its id; throws Error if a vertex slot is empty, repeated, or not in
  /// this graph.
  template <class E>
  E* addEdge(std::unique_ptr<E> edge) {
    E* raw = edge.get();
    addEdgeImpl(std::unique_ptr<EdgeBase>(std::move(edge)));
    return raw;
  }
  /// Removes and destroys an edge (no-op for an edge not in the graph).
  void removeEdge(const EdgeBase* edge);
  /// Removes a vertex and every edge attached to it.
  void removeVertex(int vertex_id);

  /// Vertex with this id or nullptr.
  VertexBase* vertex(int vertex_id) const;
  size_t numVertices() const { return vertices_.size(); }
  size_t numEdges() const { return edges_.size(); }
  std::vector<EdgeBase*> edges() const;

  /// Runs the optimiser on the edges of options.level.
  Summary optimize(const Options& options = Options());

  /// Robust chi2 of the edges of one level at the current estimates (updates edge chi2()).
  double chi2(int level = 0);

  /// Marginal covariances (blocks of H^-1 at the current estimate, H = J^T W J of the edges of
  /// options.level) of the given free vertices, in the order given. With the Schur path only
  /// non-marginalised vertices are allowed; a marginalised one switches to the full system.
  std::vector<Eigen::MatrixXd> marginalCovariance(const std::vector<int>& vertex_ids,
                                                  const Options& options = Options());

 private:
  void addVertexImpl(std::unique_ptr<VertexBase> vertex);
  void addEdgeImpl(std::unique_ptr<EdgeBase> edge);
  std::vector<EdgeBase*> activeEdges(int level) const;

  std::map<int, std::unique_ptr<VertexBase>> vertices_;
  std::vector<std::unique_ptr<EdgeBase>> edges_;  ///< in id order (ids only grow): a local BA adds thousands
  int next_edge_id_ = 0;
  /// Counts additions and removals: a vertex or edge freed and another made at the same address must
  /// not pass for the one before in the solver's structure key.
  std::uint64_t version_ = 0;
  std::unique_ptr<internal::Solver> solver_;  // keeps CHOLMOD's symbolic analysis across calls
};

}  // namespace sparse_opt
