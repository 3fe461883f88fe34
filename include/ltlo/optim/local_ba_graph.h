#pragma once
/// LocalBaGraph (namespace ltlo::optim): the graph of one local visual(-inertial) bundle adjustment,
/// kept across several optimisations so the robust VIBA of thesis Eq. 50 can alternate the
/// state/point step with static-weight updates without rebuilding it (sparse_opt keeps CHOLMOD's
/// symbolic analysis while the pattern is unchanged). localBundleAdjust() is one use of it.
///
/// Reprojection edges carry the Huber kernel of the chi2 gates (LocalBaOptions) on the unweighted
/// |r|^2 and the static weight w = beta * gamma as cost scale w^2 (Eq. 53: w^2 rho_H(|r|^2)).
/// An edge whose weight is (nearly) zero leaves the linear system (level 1), and so do the remaining
/// edges of a point that would be left under-constrained, so no point block goes singular.
/// Not thread-safe (one caller); the solver uses LocalBaOptions::num_threads internally.
#include <memory>
#include <vector>

#include <sparse_opt/graph.h>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/optim/bundle_adjust.h"

namespace ltlo::optim {

/// Static weights below this leave the linear system (their w^2 < 1e-6 would count for nothing).
constexpr double kMinActiveStaticWeight = 1e-3;

class LocalBaGraph {
 public:
  /// Builds the vertices and edges of `problem`; asserts on unknown or duplicate ids and on
  /// sigma_px <= 0 (programmer errors). The observations' static_weight are the initial weights.
  LocalBaGraph(const LocalBaProblem& problem, const LocalBaOptions& options);
  ~LocalBaGraph();
  LocalBaGraph(const LocalBaGraph&) = delete;
  LocalBaGraph& operator=(const LocalBaGraph&) = delete;

  std::size_t numObservations() const;
  /// Static weight w in [0, 1] per observation (problem order); returns how many stay in the
  /// system (w >= kMinActiveStaticWeight, and a point keeps a depth edge or two 2-D edges; a point
  /// without them keeps its position this step).
  int setStaticWeights(const std::vector<double>& weights);
  /// Runs Levenberg-Marquardt on the active reprojection edges and the inertial edges.
  sparse_opt::Summary optimize(int iterations);
  /// Unweighted whitened |r|^2 at the current estimate (all levels), and whether the point lies in
  /// front of the camera, of the observations o with wanted[o] (one flag per observation; the others
  /// get 0 and false): the static scores read the optimised keyframes' only.
  void residuals(const std::vector<bool>& wanted, std::vector<double>* r_sq, std::vector<bool>* in_front) const;
  /// ORB-SLAM's second pass: observations failing their chi2 gate (or behind the camera) leave the
  /// system and the robust kernels are removed. Returns the number still active.
  int rejectOutliers();

  /// Current estimates (problem order).
  SE3 T_w_b(std::size_t keyframe_index) const;
  Vec3 p_w(std::size_t point_index) const;
  /// Estimates, per-observation gate results and |r|^2 as LocalBaResult.
  LocalBaResult result(const sparse_opt::Summary& summary) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ltlo::optim
