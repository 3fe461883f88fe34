#include "solver.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <thread>
#include <unordered_map>

namespace sparse_opt::internal {

namespace {

constexpr double kMinDiagonal = 1e-6;
constexpr double kMaxDiagonal = 1e32;
// Damping range, as Ceres' trust-region radius range [1e-32, 1e16] with lambda = 1 / radius.
constexpr double kMinLambda = 1e-16;
constexpr double kMaxLambda = 1e32;

double clampDiagonal(double d) { return std::min(std::max(d, kMinDiagonal), kMaxDiagonal); }

/// Runs f(0) and f(1), on two threads when parallel, else one after the other; rethrows.
template <class F>
void runTwo(bool parallel, F&& f) {
  if (!parallel) {
    f(0);
    f(1);
    return;
  }
  std::exception_ptr worker_error;
  std::thread worker([&] {
    try {
      f(1);
    } catch (...) {
      worker_error = std::current_exception();
    }
  });
  std::exception_ptr main_error;
  try {
    f(0);
  } catch (...) {
    main_error = std::current_exception();
  }
  worker.join();
  if (main_error) std::rethrow_exception(main_error);
  if (worker_error) std::rethrow_exception(worker_error);
}

// Below these sizes a phase takes well under a millisecond and starting a thread (which on a busy
// machine may wait for a core) costs more than it saves. Results do not depend on it.
constexpr int kMinParallelEdges = 20000;
constexpr int kMinParallelLandmarks = 4000;

/// Splits [0, n) into two halves; the second runs on a worker thread when num_threads > 1 and
/// n >= min_parallel. The split does not depend on either, so results are identical.
template <class F>
void runHalves(int num_threads, int n, int min_parallel, F&& f) {
  const int mid = n / 2;
  runTwo(num_threads > 1 && n >= min_parallel, [&](int t) { f(t == 0 ? 0 : mid, t == 0 ? mid : n, t); });
}

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// Adds the lifetime of the object to a stage time.
class StageTimer {
 public:
  explicit StageTimer(double& total_s) : total_s_(total_s), start_(std::chrono::steady_clock::now()) {}
  ~StageTimer() { total_s_ += secondsSince(start_); }
  StageTimer(const StageTimer&) = delete;
  StageTimer& operator=(const StageTimer&) = delete;

 private:
  double& total_s_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace

void Solver::throwNonFinite(int edge_index, const char* what) const {
  const EdgeBase* e = edges_[static_cast<size_t>(edge_index)];
  throw Error("sparse_opt: edge " + std::to_string(e->id()) + " (" + e->typeName() + ") has a non-finite " +
              what + ": " + e->describeValues());
}

void Solver::setup(const std::vector<EdgeBase*>& edges, bool use_schur, std::uint64_t graph_version) {
  StructureKey& key = candidate_key_;
  key.use_schur = use_schur;
  key.graph_version = graph_version;
  key.pointers.clear();
  key.vertex_states.clear();
  for (const EdgeBase* e : edges) {
    key.pointers.push_back(e);
    for (int s = 0; s < e->numVertices(); ++s) {
      const VertexBase* v = e->vertex(s);
      key.pointers.push_back(v);
      key.vertex_states.push_back(v->dimension() * 4 + (v->marginalized() ? 2 : 0) + (v->fixed() ? 1 : 0));
    }
  }
  reused_structure_ = structure_valid_ && key == structure_key_;
  if (reused_structure_) {
    resetBuffers();
    return;
  }
  structure_valid_ = false;
  std::swap(structure_key_, candidate_key_);
  use_schur_ = use_schur;
  edges_ = edges;
  cameras_.clear();
  landmarks_.clear();
  // VertexBase::solver_index_ >= 0: camera index; <= -2: landmark -(index + 2).
  constexpr int kUnset = std::numeric_limits<int>::min() + 1;
  for (EdgeBase* e : edges_) {
    for (int s = 0; s < e->numVertices(); ++s) e->vertex(s)->solver_index_ = kUnset;
  }
  for (EdgeBase* e : edges_) {
    for (int s = 0; s < e->numVertices(); ++s) {
      VertexBase* v = e->vertex(s);
      if (v->fixed() || v->solver_index_ != kUnset) continue;
      if (use_schur && v->marginalized()) {
        v->solver_index_ = -2 - static_cast<int>(landmarks_.size());
        landmarks_.push_back(v);
      } else {
        v->solver_index_ = static_cast<int>(cameras_.size());
        cameras_.push_back(v);
      }
    }
  }
  const int nc = static_cast<int>(cameras_.size());
  const int nl = static_cast<int>(landmarks_.size());
  cam_dim_.resize(nc);
  cam_offset_.resize(nc + 1);
  cam_offset_[0] = 0;
  for (int i = 0; i < nc; ++i) {
    cam_dim_[i] = cameras_[i]->dimension();
    cam_offset_[i + 1] = cam_offset_[i] + cam_dim_[i];
  }
  cam_total_ = cam_offset_[nc];
  lm_dim_.resize(nl);
  lm_offset_.resize(nl + 1);
  hll_offset_.resize(nl + 1);
  lm_offset_[0] = hll_offset_[0] = 0;
  for (int l = 0; l < nl; ++l) {
    lm_dim_[l] = landmarks_[l]->dimension();
    lm_offset_[l + 1] = lm_offset_[l] + lm_dim_[l];
    hll_offset_[l + 1] = hll_offset_[l] + lm_dim_[l] * lm_dim_[l];
  }
  lm_total_ = lm_offset_[nl];

  // Edges sorted by landmark (stable counting sort; landmark-free edges last) so that threads
  // can own landmarks.
  {
    std::vector<int> key(edges_.size(), nl);
    std::vector<int> count(static_cast<size_t>(nl) + 2, 0);
    for (size_t k = 0; k < edges_.size(); ++k) {
      const EdgeBase* e = edges_[k];
      for (int s = 0; s < e->numVertices(); ++s) {
        const VertexBase* v = e->vertex(s);
        if (!v->fixed() && v->solver_index_ <= -2) key[k] = -2 - v->solver_index_;
      }
      ++count[static_cast<size_t>(key[k]) + 1];
    }
    for (int l = 0; l <= nl; ++l) count[l + 1] += count[l];
    std::vector<EdgeBase*> sorted(edges_.size());
    std::vector<int> sorted_key(edges_.size());
    for (size_t k = 0; k < edges_.size(); ++k) {
      const int pos = count[key[k]]++;
      sorted[pos] = edges_[k];
      sorted_key[pos] = key[k];
    }
    edges_.swap(sorted);
    const int n = static_cast<int>(edges_.size());
    edge_split_ = n / 2;
    while (edge_split_ > 0 && edge_split_ < n && sorted_key[edge_split_] < nl &&
           sorted_key[edge_split_ - 1] == sorted_key[edge_split_]) {
      ++edge_split_;
    }
    landmark_split_ = edge_split_ < n ? sorted_key[edge_split_] : nl;
  }

  // Pass 1: camera pairs and camera-landmark pairs.
  std::vector<uint64_t> cam_pairs;  // (col << 32) | row, row <= col
  std::vector<uint64_t> obs_pairs;  // (landmark << 32) | camera
  cam_pairs.reserve(static_cast<size_t>(nc) + edges_.size());
  obs_pairs.reserve(edges_.size());
  for (int i = 0; i < nc; ++i) cam_pairs.push_back((static_cast<uint64_t>(i) << 32) | static_cast<uint64_t>(i));
  auto slotIndex = [&](const EdgeBase* e, int s) {
    const VertexBase* v = e->vertex(s);
    return v->fixed() ? std::numeric_limits<int>::min() : v->solver_index_;
  };
  for (size_t k = 0; k < edges_.size(); ++k) {
    const EdgeBase* e = edges_[k];
    int num_landmarks = 0;
    for (int a = 0; a < e->numVertices(); ++a) {
      const int ia = slotIndex(e, a);
      if (ia == std::numeric_limits<int>::min()) continue;
      if (ia <= -2) ++num_landmarks;
      for (int b = a + 1; b < e->numVertices(); ++b) {
        const int ib = slotIndex(e, b);
        if (ib == std::numeric_limits<int>::min()) continue;
        if (ia >= 0 && ib >= 0) {
          cam_pairs.push_back((static_cast<uint64_t>(std::max(ia, ib)) << 32) | static_cast<uint64_t>(std::min(ia, ib)));
        } else if (ia >= 0 || ib >= 0) {
          const int cam = ia >= 0 ? ia : ib;
          const int lm = -2 - (ia >= 0 ? ib : ia);
          obs_pairs.push_back((static_cast<uint64_t>(lm) << 32) | static_cast<uint64_t>(cam));
        }
      }
    }
    if (num_landmarks > 1) {
      throw Error("sparse_opt: edge " + std::to_string(e->id()) + " (" + e->typeName() +
                  ") connects more than one marginalized vertex; the Schur complement needs at most one "
                  "per edge (use Options::use_schur = false)");
    }
  }
  std::sort(obs_pairs.begin(), obs_pairs.end());
  obs_pairs.erase(std::unique(obs_pairs.begin(), obs_pairs.end()), obs_pairs.end());
  const int num_obs = static_cast<int>(obs_pairs.size());
  lm_obs_start_.assign(nl + 1, 0);
  obs_cam_.resize(num_obs);
  obs_offset_.resize(num_obs + 1);
  obs_offset_[0] = 0;
  for (int o = 0; o < num_obs; ++o) {
    const int lm = static_cast<int>(obs_pairs[o] >> 32);
    obs_cam_[o] = static_cast<int>(obs_pairs[o] & 0xffffffffu);
    ++lm_obs_start_[lm + 1];
    obs_offset_[o + 1] = obs_offset_[o] + cam_dim_[obs_cam_[o]] * lm_dim_[lm];
  }
  max_obs_ = 0;
  for (int l = 0; l < nl; ++l) {
    max_obs_ = std::max(max_obs_, lm_obs_start_[l + 1]);
    lm_obs_start_[l + 1] += lm_obs_start_[l];
  }
  // Schur fill-in: every camera pair sharing a landmark.
  for (int l = 0; l < nl; ++l) {
    for (int p = lm_obs_start_[l]; p < lm_obs_start_[l + 1]; ++p) {
      for (int q = p + 1; q < lm_obs_start_[l + 1]; ++q) {
        cam_pairs.push_back((static_cast<uint64_t>(obs_cam_[q]) << 32) | static_cast<uint64_t>(obs_cam_[p]));
      }
    }
  }
  std::sort(cam_pairs.begin(), cam_pairs.end());
  cam_pairs.erase(std::unique(cam_pairs.begin(), cam_pairs.end()), cam_pairs.end());
  const int num_blocks = static_cast<int>(cam_pairs.size());
  blk_col_start_.assign(nc + 1, 0);
  blk_row_.resize(num_blocks);
  blk_offset_.resize(num_blocks + 1);
  blk_x_base_.resize(num_blocks);
  diag_block_.resize(nc);
  blk_offset_[0] = 0;
  for (int k = 0; k < num_blocks; ++k) {
    const int col = static_cast<int>(cam_pairs[k] >> 32);
    const int row = static_cast<int>(cam_pairs[k] & 0xffffffffu);
    blk_row_[k] = row;
    ++blk_col_start_[col + 1];
    blk_offset_[k + 1] = blk_offset_[k] + cam_dim_[row] * cam_dim_[col];
    if (row == col) diag_block_[col] = k;
  }
  for (int i = 0; i < nc; ++i) blk_col_start_[i + 1] += blk_col_start_[i];
  cam_pairs.clear();
  cam_pairs.shrink_to_fit();
  auto findBlock = [&](int row, int col) {
    const auto begin = blk_row_.begin() + blk_col_start_[col];
    const auto end = blk_row_.begin() + blk_col_start_[col + 1];
    return static_cast<int>(std::lower_bound(begin, end, row) - blk_row_.begin());
  };
  auto findObs = [&](int lm, int cam) {
    const auto begin = obs_cam_.begin() + lm_obs_start_[lm];
    const auto end = obs_cam_.begin() + lm_obs_start_[lm + 1];
    return static_cast<int>(std::lower_bound(begin, end, cam) - obs_cam_.begin());
  };
  lm_pair_start_.assign(nl + 1, 0);
  pair_block_.clear();
  lm_fast_.assign(nl, 0);
  for (int l = 0; l < nl; ++l) {
    bool fast = lm_dim_[l] == 3;
    for (int p = lm_obs_start_[l]; p < lm_obs_start_[l + 1]; ++p) {
      fast = fast && cam_dim_[obs_cam_[p]] == 6;
      for (int q = p; q < lm_obs_start_[l + 1]; ++q) pair_block_.push_back(findBlock(obs_cam_[p], obs_cam_[q]));
    }
    lm_fast_[l] = fast ? 1 : 0;
    lm_pair_start_[l + 1] = static_cast<int>(pair_block_.size());
  }

  // Pass 2: where each edge writes.
  edge_write_start_.assign(edges_.size() + 1, 0);
  writes_.clear();
  writes_.reserve(edges_.size() * 5);
  for (size_t k = 0; k < edges_.size(); ++k) {
    const EdgeBase* e = edges_[k];
    for (int a = 0; a < e->numVertices(); ++a) {
      const int ia = slotIndex(e, a);
      if (ia == std::numeric_limits<int>::min()) continue;
      if (ia >= 0) {
        writes_.push_back({a, -1, BlockWrite::kCameraGradient, cam_offset_[ia]});
        writes_.push_back({a, a, BlockWrite::kCameraPair, blk_offset_[diag_block_[ia]]});
      } else {
        writes_.push_back({a, -1, BlockWrite::kLandmarkGradient, lm_offset_[-2 - ia]});
        writes_.push_back({a, a, BlockWrite::kLandmark, hll_offset_[-2 - ia]});
      }
      for (int b = a + 1; b < e->numVertices(); ++b) {
        const int ib = slotIndex(e, b);
        if (ib == std::numeric_limits<int>::min()) continue;
        if (ia >= 0 && ib >= 0) {
          if (ia < ib) {
            writes_.push_back({a, b, BlockWrite::kCameraPair, blk_offset_[findBlock(ia, ib)]});
          } else {
            writes_.push_back({b, a, BlockWrite::kCameraPair, blk_offset_[findBlock(ib, ia)]});
          }
        } else if (ia >= 0) {
          writes_.push_back({a, b, BlockWrite::kCameraLandmark, obs_offset_[findObs(-2 - ib, ia)]});
        } else {
          writes_.push_back({b, a, BlockWrite::kCameraLandmark, obs_offset_[findObs(-2 - ia, ib)]});
        }
      }
    }
    edge_write_start_[k + 1] = static_cast<int>(writes_.size());
  }

  // Scalar upper-triangular pattern of the reduced system.
  pattern_col_start_.assign(static_cast<size_t>(cam_total_) + 1, 0);
  pattern_row_.clear();
  for (int j = 0; j < nc; ++j) {
    int base = 0;
    for (int k = blk_col_start_[j]; k < blk_col_start_[j + 1]; ++k) {
      blk_x_base_[k] = base;
      base += cam_dim_[blk_row_[k]];
    }
    for (int cc_col = 0; cc_col < cam_dim_[j]; ++cc_col) {
      const int c = cam_offset_[j] + cc_col;
      for (int k = blk_col_start_[j]; k < blk_col_start_[j + 1]; ++k) {
        const int i = blk_row_[k];
        const int rows = (i == j) ? cc_col + 1 : cam_dim_[i];
        for (int r = 0; r < rows; ++r) pattern_row_.push_back(cam_offset_[i] + r);
      }
      pattern_col_start_[c + 1] = static_cast<int>(pattern_row_.size());
    }
  }

  resetBuffers();
  structure_valid_ = true;
}

void Solver::resetBuffers() {
  const int nc = static_cast<int>(cameras_.size());
  const int nl = static_cast<int>(landmarks_.size());
  const int num_blocks = blk_col_start_.empty() ? 0 : blk_col_start_[nc];
  const int num_obs = lm_obs_start_.empty() ? 0 : lm_obs_start_[nl];
  hcc_.assign(static_cast<size_t>(blk_offset_[num_blocks]), 0.0);
  hcc_other_.assign(hcc_.size(), 0.0);
  s_.assign(hcc_.size(), 0.0);
  s_other_.assign(hcc_.size(), 0.0);
  hcl_.assign(static_cast<size_t>(obs_offset_[num_obs]), 0.0);
  hll_.assign(static_cast<size_t>(hll_offset_[nl]), 0.0);
  hll_inv_.assign(hll_.size(), 0.0);
  for (auto& s : scratch_) s.assign(static_cast<size_t>(std::max(1, max_obs_) * 6 * 6), 0.0);
  int max_dc = 6, max_dl = 3;
  for (int d : cam_dim_) max_dc = std::max(max_dc, d);
  for (int d : lm_dim_) max_dl = std::max(max_dl, d);
  for (auto& s : scratch_) s.assign(static_cast<size_t>(std::max(1, max_obs_) * max_dc * max_dl), 0.0);
  bc_.setZero(cam_total_);
  bc_other_.setZero(cam_total_);
  rc_.setZero(cam_total_);
  rc_other_.setZero(cam_total_);
  dxc_.setZero(cam_total_);
  diag_c_.setZero(cam_total_);
  bl_.setZero(lm_total_);
  dxl_.setZero(lm_total_);
  diag_l_.setZero(lm_total_);
}

double Solver::evaluateChi2(int num_threads) {
  const StageTimer timer(times_.evaluate_s);
  const int n = static_cast<int>(edges_.size());
  double partial[2] = {0.0, 0.0};
  int bad[2] = {-1, -1};
  runHalves(num_threads, n, kMinParallelEdges, [&](int begin, int end, int t) {
    double sum = 0.0;
    for (int k = begin; k < end; ++k) {
      sum += edges_[k]->evaluateChi2();
      if (bad[t] < 0 && !edges_[k]->errorFinite()) bad[t] = k;
    }
    partial[t] = sum;
  });
  if (bad[0] >= 0) throwNonFinite(bad[0], "residual");
  if (bad[1] >= 0) throwNonFinite(bad[1], "residual");
  return partial[0] + partial[1];
}

void Solver::linearizeAndAccumulate(int num_threads) {
  const StageTimer timer(times_.linearize_s);
  const int nl = static_cast<int>(landmarks_.size());
  const int nc = static_cast<int>(cameras_.size());
  const int n = static_cast<int>(edges_.size());
  int bad[2] = {-1, -1};
  auto work = [&](int t) {
    const int edge_begin = t == 0 ? 0 : edge_split_;
    const int edge_end = t == 0 ? edge_split_ : n;
    const int lm_begin = t == 0 ? 0 : landmark_split_;
    const int lm_end = t == 0 ? landmark_split_ : nl;
    double* hcc = t == 0 ? hcc_.data() : hcc_other_.data();
    double* bc = t == 0 ? bc_.data() : bc_other_.data();
    std::fill(hcc, hcc + hcc_.size(), 0.0);
    std::fill(bc, bc + cam_total_, 0.0);
    std::fill(hcl_.data() + obs_offset_[lm_obs_start_[lm_begin]], hcl_.data() + obs_offset_[lm_obs_start_[lm_end]], 0.0);
    std::fill(hll_.data() + hll_offset_[lm_begin], hll_.data() + hll_offset_[lm_end], 0.0);
    std::fill(bl_.data() + lm_offset_[lm_begin], bl_.data() + lm_offset_[lm_end], 0.0);
    for (int k = edge_begin; k < edge_end; ++k) {
      EdgeBase* e = edges_[k];
      if (!e->linearizeAtError()) {  // every call follows evaluateChi2() at the same estimates
        if (bad[t] < 0) bad[t] = k;
        continue;
      }
      for (int w = edge_write_start_[k]; w < edge_write_start_[k + 1]; ++w) {
        const BlockWrite& item = writes_[w];
        switch (item.target) {
          case BlockWrite::kCameraPair: e->addHessianBlock(item.a, item.b, hcc + item.offset); break;
          case BlockWrite::kCameraLandmark: e->addHessianBlock(item.a, item.b, hcl_.data() + item.offset); break;
          case BlockWrite::kLandmark: e->addHessianBlock(item.a, item.b, hll_.data() + item.offset); break;
          case BlockWrite::kCameraGradient: e->addGradient(item.a, bc + item.offset); break;
          case BlockWrite::kLandmarkGradient: e->addGradient(item.a, bl_.data() + item.offset); break;
        }
      }
    }
  };
  runTwo(num_threads > 1 && n >= kMinParallelEdges, work);
  for (int t = 0; t < 2; ++t) {
    if (bad[t] >= 0) throwNonFinite(bad[t], edges_[bad[t]]->errorFinite() ? "jacobian" : "residual");
  }
  for (size_t k = 0; k < hcc_.size(); ++k) hcc_[k] += hcc_other_[k];
  bc_ += bc_other_;
  for (int i = 0; i < nc; ++i) {
    const int d = cam_dim_[i];
    const double* block = hcc_.data() + blk_offset_[diag_block_[i]];
    for (int r = 0; r < d; ++r) diag_c_[cam_offset_[i] + r] = clampDiagonal(block[r * (d + 1)]);
  }
  for (int l = 0; l < nl; ++l) {
    const int d = lm_dim_[l];
    const double* block = hll_.data() + hll_offset_[l];
    for (int r = 0; r < d; ++r) diag_l_[lm_offset_[l] + r] = clampDiagonal(block[r * (d + 1)]);
  }
}

template <int DC, int DL>
bool Solver::schurLandmark(int l, double lambda, double* s, double* rc, double* scratch) {
  using MatLL = Eigen::Matrix<double, DL, DL>;
  using MatCL = Eigen::Matrix<double, DC, DL>;
  using VecL = Eigen::Matrix<double, DL, 1>;
  using VecC = Eigen::Matrix<double, DC, 1>;
  using MatCC = Eigen::Matrix<double, DC, DC>;
  const int dl = lm_dim_[l];
  const Eigen::Map<const MatLL> hll(hll_.data() + hll_offset_[l], dl, dl);
  MatLL damped = hll;
  for (int d = 0; d < dl; ++d) damped(d, d) += lambda * diag_l_[lm_offset_[l] + d];
  const Eigen::LLT<MatLL> llt(damped);
  if (llt.info() != Eigen::Success) return false;
  Eigen::Map<MatLL> inv(hll_inv_.data() + hll_offset_[l], dl, dl);
  inv = llt.solve(MatLL::Identity(dl, dl));
  const Eigen::Map<const VecL> bl(bl_.data() + lm_offset_[l], dl);
  const int o_begin = lm_obs_start_[l];
  const int o_end = lm_obs_start_[l + 1];
  int scratch_pos = 0;
  for (int o = o_begin; o < o_end; ++o) {
    const int dc = cam_dim_[obs_cam_[o]];
    const Eigen::Map<const MatCL> hcl(hcl_.data() + obs_offset_[o], dc, dl);
    Eigen::Map<MatCL> t(scratch + scratch_pos, dc, dl);
    scratch_pos += dc * dl;
    t.noalias() = hcl * inv;
    Eigen::Map<VecC>(rc + cam_offset_[obs_cam_[o]], dc).noalias() -= t * bl;
  }
  int pair = lm_pair_start_[l];
  int pos_p = 0;
  for (int p = o_begin; p < o_end; ++p) {
    const int dp = cam_dim_[obs_cam_[p]];
    const Eigen::Map<const MatCL> tp(scratch + pos_p, dp, dl);
    pos_p += dp * dl;
    for (int q = p; q < o_end; ++q) {
      const int dq = cam_dim_[obs_cam_[q]];
      const Eigen::Map<const MatCL> hql(hcl_.data() + obs_offset_[q], dq, dl);
      Eigen::Map<MatCC> block(s + blk_offset_[pair_block_[pair++]], dp, dq);
      block.noalias() -= tp * hql.transpose();
    }
  }
  return true;
}

template <int DC, int DL>
void Solver::backSubstituteLandmark(int l) {
  using MatLL = Eigen::Matrix<double, DL, DL>;
  using MatCL = Eigen::Matrix<double, DC, DL>;
  using VecL = Eigen::Matrix<double, DL, 1>;
  using VecC = Eigen::Matrix<double, DC, 1>;
  const int dl = lm_dim_[l];
  VecL rhs = Eigen::Map<const VecL>(bl_.data() + lm_offset_[l], dl);
  for (int o = lm_obs_start_[l]; o < lm_obs_start_[l + 1]; ++o) {
    const int i = obs_cam_[o];
    const int dc = cam_dim_[i];
    const Eigen::Map<const MatCL> hcl(hcl_.data() + obs_offset_[o], dc, dl);
    rhs.noalias() -= hcl.transpose() * Eigen::Map<const VecC>(dxc_.data() + cam_offset_[i], dc);
  }
  const Eigen::Map<const MatLL> inv(hll_inv_.data() + hll_offset_[l], dl, dl);
  Eigen::Map<VecL>(dxl_.data() + lm_offset_[l], dl).noalias() = inv * rhs;
}

bool Solver::factorizeReduced(const Options& options) {
  if (cam_total_ == 0) return true;
  if (!use_cholmod_) {
    dense_.setZero(cam_total_, cam_total_);
    const int nc = static_cast<int>(cameras_.size());
    for (int j = 0; j < nc; ++j) {
      for (int k = blk_col_start_[j]; k < blk_col_start_[j + 1]; ++k) {
        const int i = blk_row_[k];
        const Eigen::Map<const Eigen::MatrixXd> block(s_.data() + blk_offset_[k], cam_dim_[i], cam_dim_[j]);
        dense_.block(cam_offset_[i], cam_offset_[j], cam_dim_[i], cam_dim_[j]) = block;
      }
    }
    Eigen::LLT<Eigen::MatrixXd, Eigen::Upper> llt(dense_);
    if (llt.info() != Eigen::Success) return false;
    dense_ = llt.matrixLLT();
    return true;
  }
  double* x = cholmod_.values();
  const int nc = static_cast<int>(cameras_.size());
  for (int j = 0; j < nc; ++j) {
    const int dj = cam_dim_[j];
    for (int k = blk_col_start_[j]; k < blk_col_start_[j + 1]; ++k) {
      const int i = blk_row_[k];
      const int di = cam_dim_[i];
      const double* block = s_.data() + blk_offset_[k];
      for (int c = 0; c < dj; ++c) {
        double* dst = x + pattern_col_start_[cam_offset_[j] + c] + blk_x_base_[k];
        const int rows = (i == j) ? c + 1 : di;
        std::copy(block + c * di, block + c * di + rows, dst);
      }
    }
  }
  return cholmod_.factorize();
}

void Solver::solveReduced(const double* rhs, double* x) {
  if (cam_total_ == 0) return;
  if (!use_cholmod_) {
    Eigen::Map<Eigen::VectorXd> out(x, cam_total_);
    out = Eigen::Map<const Eigen::VectorXd>(rhs, cam_total_);
    dense_.triangularView<Eigen::Upper>().transpose().solveInPlace(out);
    dense_.triangularView<Eigen::Upper>().solveInPlace(out);
    return;
  }
  cholmod_.solve(rhs, x);
}

bool Solver::solveStep(double lambda, const Options& options) {
  auto schur_start = std::chrono::steady_clock::now();
  const int nl = static_cast<int>(landmarks_.size());
  s_ = hcc_;
  const int nc = static_cast<int>(cameras_.size());
  for (int i = 0; i < nc; ++i) {
    const int d = cam_dim_[i];
    double* block = s_.data() + blk_offset_[diag_block_[i]];
    for (int r = 0; r < d; ++r) block[r * (d + 1)] += lambda * diag_c_[cam_offset_[i] + r];
  }
  rc_ = bc_;
  if (nl > 0) {
    std::fill(s_other_.begin(), s_other_.end(), 0.0);
    rc_other_.setZero();
    bool ok[2] = {true, true};
    runHalves(options.num_threads, nl, kMinParallelLandmarks, [&](int begin, int end, int t) {
      double* s = t == 0 ? s_.data() : s_other_.data();
      double* rc = t == 0 ? rc_.data() : rc_other_.data();
      double* scratch = scratch_[t].data();
      for (int l = begin; l < end && ok[t]; ++l) {
        ok[t] = lm_fast_[l] ? schurLandmark<6, 3>(l, lambda, s, rc, scratch)
                            : schurLandmark<Eigen::Dynamic, Eigen::Dynamic>(l, lambda, s, rc, scratch);
      }
    });
    if (!ok[0] || !ok[1]) return false;
    for (size_t k = 0; k < s_.size(); ++k) s_[k] += s_other_[k];
    rc_ += rc_other_;
  }
  times_.schur_s += secondsSince(schur_start);
  {
    const StageTimer timer(times_.factorize_s);
    if (!factorizeReduced(options)) return false;
    solveReduced(rc_.data(), dxc_.data());
  }
  schur_start = std::chrono::steady_clock::now();
  if (nl > 0) {
    runHalves(options.num_threads, nl, kMinParallelLandmarks, [&](int begin, int end, int) {
      for (int l = begin; l < end; ++l) {
        if (lm_fast_[l]) {
          backSubstituteLandmark<6, 3>(l);
        } else {
          backSubstituteLandmark<Eigen::Dynamic, Eigen::Dynamic>(l);
        }
      }
    });
  }
  times_.schur_s += secondsSince(schur_start);
  return dxc_.allFinite() && dxl_.allFinite();
}

double Solver::predictedDecrease(double lambda) const {
  // Model decrease of 0.5 chi2: dx^T b - 0.5 dx^T H dx = 0.5 dx^T (b + lambda D dx).
  const double cams = dxc_.dot(bc_ + lambda * diag_c_.cwiseProduct(dxc_));
  const double lms = dxl_.dot(bl_ + lambda * diag_l_.cwiseProduct(dxl_));
  return 0.5 * (cams + lms);
}

double Solver::gradientMaxNorm() const {
  double g = 0.0;
  if (bc_.size() > 0) g = std::max(g, bc_.cwiseAbs().maxCoeff());
  if (bl_.size() > 0) g = std::max(g, bl_.cwiseAbs().maxCoeff());
  return g;
}

void Solver::applyStep() {
  for (size_t i = 0; i < cameras_.size(); ++i) {
    cameras_[i]->saveForRollback();
    cameras_[i]->oplus(dxc_.data() + cam_offset_[i]);
  }
  for (size_t l = 0; l < landmarks_.size(); ++l) {
    landmarks_[l]->saveForRollback();
    landmarks_[l]->oplus(dxl_.data() + lm_offset_[l]);
  }
}

void Solver::rollbackStep() {
  for (VertexBase* v : cameras_) v->rollback();
  for (VertexBase* v : landmarks_) v->rollback();
}

Summary Solver::run(const Options& options) {
  const auto start = std::chrono::steady_clock::now();
  Summary summary;
  summary.used_schur = use_schur_ && !landmarks_.empty();
  summary.reduced_dimension = cam_total_;
  summary.reused_structure = reused_structure_;
  use_cholmod_ = options.linear_solver == LinearSolverType::kCholmod ||
                 (options.linear_solver == LinearSolverType::kAuto && cam_total_ > options.dense_max_dimension);
  summary.used_cholmod = use_cholmod_;
  if (use_cholmod_ && cam_total_ > 0) {
    const StageTimer timer(times_.setup_s);
    reused_symbolic_ = cholmod_.setPattern(cam_total_, pattern_col_start_, pattern_row_);
    summary.reused_symbolic = reused_symbolic_;
  }
  const bool lm = options.algorithm == Algorithm::kLevenbergMarquardt;
  double chi2 = evaluateChi2(options.num_threads);
  // The edges' residuals and chi2 describe the current estimates (false after a rolled-back trial).
  bool evaluated_at_estimates = true;
  summary.initial_chi2 = chi2;
  summary.final_chi2 = chi2;
  if (cam_total_ + lm_total_ == 0) {
    summary.converged = true;
    summary.termination = "no free vertices";
    summary.total_time_s = secondsSince(start);
    return summary;
  }
  linearizeAndAccumulate(options.num_threads);
  double lambda = lm ? options.initial_lambda : 0.0;
  double nu = 2.0;
  summary.termination = "maximum iterations reached";
  if (gradientMaxNorm() <= options.gradient_tolerance) {
    summary.converged = true;
    summary.termination = "gradient tolerance";
  }
  for (int iteration = 0; iteration < options.max_iterations && !summary.converged; ++iteration) {
    if (options.stop_flag != nullptr && options.stop_flag->load()) {
      summary.termination = "stopped by request";
      break;
    }
    IterationStats stats;
    stats.iteration = iteration;
    stats.lambda = lambda;
    ++summary.iterations;
    const bool solved = solveStep(lambda, options);
    if (!solved) {
      if (!lm) {
        summary.termination = "linear system not positive definite";
        break;
      }
      lambda *= nu;
      nu *= 2.0;
      stats.chi2 = chi2;
      stats.time_s = secondsSince(start);
      summary.history.push_back(stats);
      if (lambda > kMaxLambda) {
        summary.termination = "linear system not positive definite at any damping";
        break;
      }
      continue;
    }
    const double step_norm = std::sqrt(dxc_.squaredNorm() + dxl_.squaredNorm());
    if (step_norm <= options.parameter_tolerance) {
      summary.converged = true;
      summary.termination = "parameter tolerance";
      stats.chi2 = chi2;
      stats.time_s = secondsSince(start);
      summary.history.push_back(stats);
      break;
    }
    const double predicted = predictedDecrease(lambda);
    applyStep();
    const double new_chi2 = evaluateChi2(options.num_threads);
    const double actual = 0.5 * (chi2 - new_chi2);
    const double rho = predicted > 0.0 ? actual / predicted : -1.0;
    if (!lm || rho > 1e-3) {
      stats.accepted = true;
      ++summary.accepted_iterations;
      if (lm) {
        const double f = 2.0 * rho - 1.0;
        lambda = std::max(kMinLambda, lambda * std::max(1.0 / 3.0, 1.0 - f * f * f));
        nu = 2.0;
      }
      const double relative_decrease = (chi2 - new_chi2) / std::max(chi2, std::numeric_limits<double>::min());
      chi2 = new_chi2;
      evaluated_at_estimates = true;
      if (std::abs(relative_decrease) <= options.function_tolerance) {
        summary.converged = true;
        summary.termination = "function tolerance";
      } else {
        linearizeAndAccumulate(options.num_threads);
        if (gradientMaxNorm() <= options.gradient_tolerance) {
          summary.converged = true;
          summary.termination = "gradient tolerance";
        }
      }
    } else {
      rollbackStep();
      evaluated_at_estimates = false;
      lambda *= nu;
      nu *= 2.0;
    }
    if (lm && lambda > kMaxLambda) {
      summary.termination = "damping too large (no decrease possible)";
      summary.converged = true;
    }
    stats.chi2 = chi2;
    stats.time_s = secondsSince(start);
    summary.history.push_back(stats);
  }
  // Edge chi2() must describe the final estimate: evaluated again only if the last trial was
  // rolled back (the same sum otherwise, in the same order).
  summary.final_chi2 = evaluated_at_estimates ? chi2 : evaluateChi2(options.num_threads);
  summary.stage_times = times_;
  summary.total_time_s = secondsSince(start) + structure_setup_s_;
  return summary;
}

std::vector<Eigen::MatrixXd> Solver::covariance(const std::vector<const VertexBase*>& vertices, const Options& options) {
  use_cholmod_ = options.linear_solver == LinearSolverType::kCholmod ||
                 (options.linear_solver == LinearSolverType::kAuto && cam_total_ > options.dense_max_dimension);
  if (use_cholmod_ && cam_total_ > 0) cholmod_.setPattern(cam_total_, pattern_col_start_, pattern_row_);
  evaluateChi2(options.num_threads);
  linearizeAndAccumulate(options.num_threads);
  if (!solveStep(0.0, options)) throw Error("sparse_opt: marginalCovariance: the Hessian is not positive definite");
  std::vector<Eigen::MatrixXd> result;
  Eigen::VectorXd unit = Eigen::VectorXd::Zero(cam_total_);
  Eigen::VectorXd column(cam_total_);
  for (const VertexBase* v : vertices) {
    const auto it = std::find(cameras_.begin(), cameras_.end(), v);
    if (it == cameras_.end()) {
      throw Error("sparse_opt: marginalCovariance: vertex " + std::to_string(v->id()) +
                  " is fixed, marginalized under Schur, or has no active edge");
    }
    const int i = static_cast<int>(it - cameras_.begin());
    const int d = cam_dim_[i];
    Eigen::MatrixXd cov(d, d);
    for (int c = 0; c < d; ++c) {
      unit[cam_offset_[i] + c] = 1.0;
      solveReduced(unit.data(), column.data());
      unit[cam_offset_[i] + c] = 0.0;
      cov.col(c) = column.segment(cam_offset_[i], d);
    }
    result.push_back(0.5 * (cov + cov.transpose()));
  }
  return result;
}

}  // namespace sparse_opt::internal
