#include "cholmod_solver.h"

#include <algorithm>
#include <cstring>

#include "sparse_opt/edge.h"

namespace sparse_opt::internal {

CholmodSolver::CholmodSolver() {
  cholmod_start(&common_);
  common_.supernodal = CHOLMOD_AUTO;  // CHOLMOD picks supernodal when the factor is dense enough
  // AMD only: the default also tries METIS/NESDIS, whose analysis costs more than it saves on
  // the banded reduced camera systems of SLAM.
  common_.nmethods = 1;
  common_.method[0].ordering = CHOLMOD_AMD;
  common_.postorder = 1;
  common_.print = 0;
}

CholmodSolver::~CholmodSolver() {
  freeAll();
  cholmod_finish(&common_);
}

void CholmodSolver::freeAll() {
  if (matrix_ != nullptr) cholmod_free_sparse(&matrix_, &common_);
  if (factor_ != nullptr) cholmod_free_factor(&factor_, &common_);
  if (rhs_ != nullptr) cholmod_free_dense(&rhs_, &common_);
  if (solution_ != nullptr) cholmod_free_dense(&solution_, &common_);
  if (work_y_ != nullptr) cholmod_free_dense(&work_y_, &common_);
  if (work_e_ != nullptr) cholmod_free_dense(&work_e_, &common_);
}

bool CholmodSolver::setPattern(int n, const std::vector<int>& col_start, const std::vector<int>& row_index) {
  if (factor_ != nullptr && n == n_ && col_start == col_start_ && row_index == row_index_) return true;
  freeAll();
  n_ = n;
  col_start_ = col_start;
  row_index_ = row_index;
  const size_t nnz = static_cast<size_t>(col_start.back());
  matrix_ = cholmod_allocate_sparse(static_cast<size_t>(n), static_cast<size_t>(n), nnz, /*sorted=*/1,
                                    /*packed=*/1, /*stype=*/1, CHOLMOD_REAL, &common_);
  if (matrix_ == nullptr) throw Error("sparse_opt: CHOLMOD could not allocate the reduced system");
  std::memcpy(matrix_->p, col_start.data(), sizeof(int) * col_start.size());
  std::memcpy(matrix_->i, row_index.data(), sizeof(int) * row_index.size());
  std::fill_n(static_cast<double*>(matrix_->x), nnz, 0.0);
  factor_ = cholmod_analyze(matrix_, &common_);
  if (factor_ == nullptr) throw Error("sparse_opt: CHOLMOD symbolic analysis failed");
  rhs_ = cholmod_zeros(static_cast<size_t>(n), 1, CHOLMOD_REAL, &common_);
  ++num_analyses_;
  return false;
}

bool CholmodSolver::factorize() {
  const int ok = cholmod_factorize(matrix_, factor_, &common_);
  return ok != 0 && common_.status == CHOLMOD_OK;
}

void CholmodSolver::solve(const double* b, double* x) {
  std::memcpy(rhs_->x, b, sizeof(double) * static_cast<size_t>(n_));
  if (cholmod_solve2(CHOLMOD_A, factor_, rhs_, nullptr, &solution_, nullptr, &work_y_, &work_e_, &common_) == 0)
    throw Error("sparse_opt: CHOLMOD solve failed");
  std::memcpy(x, solution_->x, sizeof(double) * static_cast<size_t>(n_));
}

}  // namespace sparse_opt::internal
