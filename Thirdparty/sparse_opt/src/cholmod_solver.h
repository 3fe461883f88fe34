// Thin RAII wrapper over CHOLMOD for a symmetric positive definite matrix given by its upper
// triangle in compressed-column form. The symbolic analysis is kept while the pattern is unchanged.
#pragma once

#include <cholmod.h>

#include <vector>

namespace sparse_opt::internal {

class CholmodSolver {
 public:
  CholmodSolver();
  ~CholmodSolver();
  CholmodSolver(const CholmodSolver&) = delete;
  CholmodSolver& operator=(const CholmodSolver&) = delete;

  /// Sets the pattern (upper triangle, sorted rows). Returns true if it equals the previous one,
  /// in which case the symbolic analysis is reused.
  bool setPattern(int n, const std::vector<int>& col_start, const std::vector<int>& row_index);
  /// Values array matching the pattern (length col_start[n]).
  double* values() { return static_cast<double*>(matrix_->x); }
  /// Numeric factorisation; false if the matrix is not positive definite.
  bool factorize();
  /// x = A^-1 b (length n each), after a successful factorize().
  void solve(const double* b, double* x);
  int numAnalyses() const { return num_analyses_; }

 private:
  void freeAll();

  cholmod_common common_;
  cholmod_sparse* matrix_ = nullptr;
  cholmod_factor* factor_ = nullptr;
  cholmod_dense* rhs_ = nullptr;
  cholmod_dense* solution_ = nullptr;
  cholmod_dense* work_y_ = nullptr;
  cholmod_dense* work_e_ = nullptr;
  std::vector<int> col_start_;
  std::vector<int> row_index_;
  int n_ = 0;
  int num_analyses_ = 0;
};

}  // namespace sparse_opt::internal
