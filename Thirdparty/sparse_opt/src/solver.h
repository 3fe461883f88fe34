// Block-sparse normal equations, Schur complement and the LM / GN loop (private to sparse_opt).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "cholmod_solver.h"
#include "sparse_opt/edge.h"
#include "sparse_opt/graph.h"

namespace sparse_opt::internal {

/// Where one edge adds J_a^T W J_b (b < 0: the gradient -J_a^T W e of slot a).
struct BlockWrite {
  enum Target : int { kCameraPair, kCameraLandmark, kLandmark, kCameraGradient, kLandmarkGradient };
  int a;
  int b;
  Target target;
  int offset;  // into the target's storage
};

class Solver {
 public:
  /// Classifies vertices and builds the block structure for these edges (throws Error on misuse);
  /// keeps the previous one when nothing it depends on changed, `graph_version` included (the
  /// graph's count of additions and removals).
  void setup(const std::vector<EdgeBase*>& edges, bool use_schur, std::uint64_t graph_version);
  /// Adds the setup time (measured by the caller) to the next run's summary.
  void setSetupTime(double seconds) {
    times_ = StageTimes();
    times_.setup_s = seconds;
    structure_setup_s_ = seconds;
  }
  Summary run(const Options& options);
  /// Blocks of H^-1 (lambda = 0) for vertices of the current setup's reduced system.
  std::vector<Eigen::MatrixXd> covariance(const std::vector<const VertexBase*>& vertices, const Options& options);

 private:
  double evaluateChi2(int num_threads);
  /// Linearises every edge at the residuals the last evaluateChi2() left (the caller's contract: no
  /// estimate changed since) and accumulates H and b. Edges are sorted by landmark and split at a
  /// landmark boundary: landmark blocks have one writer; camera blocks are summed per thread and
  /// added in a fixed order, so the result does not depend on the thread count.
  void linearizeAndAccumulate(int num_threads);
  /// Builds the damped reduced system and solves it; false if not positive definite.
  bool solveStep(double lambda, const Options& options);
  bool factorizeReduced(const Options& options);
  void solveReduced(const double* rhs, double* x);
  void applyStep();
  void rollbackStep();
  double predictedDecrease(double lambda) const;
  double gradientMaxNorm() const;
  template <int DC, int DL>
  bool schurLandmark(int l, double lambda, double* s, double* rc, double* scratch);
  template <int DC, int DL>
  void backSubstituteLandmark(int l);
  [[noreturn]] void throwNonFinite(int edge_index, const char* what) const;

  /// The zeroed accumulators and vectors of a run, sized by the structure (end of every setup).
  void resetBuffers();
  /// What the structure depends on: the edges in the order given, each one's vertices, and each
  /// vertex's fixed and marginalised flags and dimension. setup() of an unchanged key keeps the
  /// structure (a robust BA's alternations optimise the same graph with new weights).
  struct StructureKey {
    bool use_schur = true;
    std::uint64_t graph_version = 0;
    std::vector<const void*> pointers;  // per edge: the edge, then its vertices
    std::vector<int> vertex_states;     // per vertex slot: dimension * 4 + marginalised * 2 + fixed
    bool operator==(const StructureKey& other) const {
      return use_schur == other.use_schur && graph_version == other.graph_version && pointers == other.pointers &&
             vertex_states == other.vertex_states;
    }
  };
  StructureKey structure_key_;
  StructureKey candidate_key_;  // scratch for the next setup's key
  bool structure_valid_ = false;

  bool use_schur_ = true;
  std::vector<EdgeBase*> edges_;
  std::vector<VertexBase*> cameras_;    // free vertices in the reduced system
  std::vector<VertexBase*> landmarks_;  // free marginalised vertices (Schur path only)
  std::vector<int> cam_dim_, cam_offset_;
  std::vector<int> lm_dim_, lm_offset_, hll_offset_;
  std::vector<char> lm_fast_;  // landmark of dim 3 seen by cameras of dim 6 only
  int cam_total_ = 0, lm_total_ = 0, max_obs_ = 0;

  // Camera pair blocks (i <= j), compressed by block column; diagonal block last in its column.
  std::vector<int> blk_col_start_, blk_row_, blk_offset_, blk_x_base_, diag_block_;
  // Camera-landmark blocks, landmark-major, cameras ascending within a landmark.
  std::vector<int> lm_obs_start_, obs_cam_, obs_offset_;
  std::vector<int> lm_pair_start_, pair_block_;  // S block of each camera pair (p <= q) per landmark
  std::vector<int> edge_write_start_;
  std::vector<BlockWrite> writes_;
  int edge_split_ = 0, landmark_split_ = 0;

  // Numeric storage (reused across iterations).
  std::vector<double> hcc_, hcc_other_, hcl_, hll_, hll_inv_, s_, s_other_, scratch_[2];
  Eigen::VectorXd bc_, bc_other_, bl_, rc_, rc_other_, dxc_, dxl_, diag_c_, diag_l_;
  Eigen::MatrixXd dense_;

  CholmodSolver cholmod_;
  std::vector<int> pattern_col_start_, pattern_row_;
  bool use_cholmod_ = false;
  StageTimes times_;
  double structure_setup_s_ = 0.0;
  bool reused_symbolic_ = false;
  bool reused_structure_ = false;  // the last setup() kept the structure
};

}  // namespace sparse_opt::internal
