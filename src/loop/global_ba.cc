#include "ltlo/loop/global_ba.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "ltlo/core/log.h"
#include "ltlo/optim/bundle_adjust.h"
#include "map_ba.h"

namespace ltlo::loop {

GlobalBaSolution optimizeGlobalBundleAdjustment(const map::Map& map, const GlobalBaOptions& options) {
  GlobalBaSolution solution;
  GlobalBaResult& result = solution.result;
  MapBaSelection selection;
  for (const std::shared_ptr<map::KeyFrame>& kf : map.keyFrames()) {
    if (!kf->isBad()) selection.optimised.push_back(kf);
  }
  if (selection.optimised.size() < 2) return solution;
  if (std::shared_ptr<map::KeyFrame> gauge = map.keyFrame(map.gaugeKeyFrame())) selection.gauge.push_back(gauge);
  MapBaOptions build;
  const map::KeyFrame& first = *selection.optimised.front();
  build.bf_px_m = first.camera().K()(0, 0) * options.virtual_baseline_m;
  build.min_point_beta = options.min_point_beta;
  build.g_w = options.g_w;
  build.lambda_imu = options.lambda_imu;
  build.visual_variance_estimation = options.visual_variance_estimation;
  MapBaProblem built = buildMapBa(map, selection, build);
  const bool estimate_gravity = options.estimate_gravity && options.g_w && !built.problem.inertial.empty();
  built.problem.estimate_gravity = estimate_gravity;
  solution.keyframes = built.keyframes;
  solution.points = built.points;
  for (const optim::BaKeyFrame& v : built.problem.keyframes) solution.T_w_b_before.push_back(v.T_w_b);
  result.keyframes = static_cast<int>(built.keyframes.size());
  result.points = static_cast<int>(built.points.size());
  result.observations = static_cast<int>(built.problem.observations.size());
  result.inertial_links = static_cast<int>(built.problem.inertial.size());
  if (built.points.empty()) return solution;

  optim::LocalBaOptions ba_options;
  ba_options.iterations = options.iterations;
  ba_options.num_threads = options.num_threads;
  ba_options.stop_flag = options.stop_flag;
  const optim::LocalBaResult solved = optim::localBundleAdjust(built.problem, ba_options);
  if (options.stop_flag != nullptr && options.stop_flag->load()) return solution;  // discarded (invalid)
  solution.inertial = inertialKeyFrames(built);
  for (const optim::BaKeyFrame& v : solved.keyframes) {
    solution.T_w_b_after.push_back(v.T_w_b);
    solution.v_w_b_after.push_back(v.v_w_b);
    solution.bias_after.push_back(v.bias);
  }
  for (const optim::BaPoint& p : solved.points) solution.p_w_after.push_back(p.p_w);
  if (estimate_gravity && solved.g_w.allFinite()) {
    solution.g_w_after = solved.g_w;
    const double cosine = solved.g_w.normalized().dot(options.g_w->normalized());
    result.gravity_change_deg = std::acos(std::clamp(cosine, -1.0, 1.0)) * 180.0 / M_PI;
  }
  for (const bool inlier : solved.inliers) result.outliers += inlier ? 0 : 1;
  result.initial_chi2 = solved.initial_chi2;
  result.final_chi2 = solved.summary.final_chi2;
  solution.valid = true;
  return solution;
}

int applyGlobalBundleAdjustment(map::Map& map, const GlobalBaSolution& solution) {
  if (!solution.valid) return 0;
  // Correction of each keyframe, T_w_b_after * T_w_b_before^-1: the optimised ones from the
  // solution, the ones created since from their parent (always older, so visited first by id).
  std::unordered_map<map::KeyFrameId, SE3> correction;
  for (std::size_t k = 0; k < solution.keyframes.size(); ++k) {
    correction[solution.keyframes[k]->id()] = solution.T_w_b_after[k] * solution.T_w_b_before[k].inverse();
  }
  int propagated = 0;
  for (const std::shared_ptr<map::KeyFrame>& kf : map.keyFrames()) {
    if (kf->isBad()) continue;
    const auto own = correction.find(kf->id());
    if (own != correction.end()) continue;
    const auto parent = correction.find(kf->parent());
    if (parent == correction.end()) continue;
    kf->setPose_T_w_b(parent->second * kf->T_w_b());
    kf->setVelocity(parent->second.rotationMatrix() * kf->v_w_b());
    correction[kf->id()] = parent->second;
    ++propagated;
  }
  for (std::size_t k = 0; k < solution.keyframes.size(); ++k) {
    map::KeyFrame& kf = *solution.keyframes[k];
    if (kf.isBad()) continue;
    kf.setPose_T_w_b(solution.T_w_b_after[k]);
    if (solution.inertial[k]) {
      kf.setVelocity(solution.v_w_b_after[k]);
      kf.setBias(solution.bias_after[k]);
    }
  }
  std::unordered_set<map::MapPointId> optimised;
  for (std::size_t p = 0; p < solution.points.size(); ++p) {
    optimised.insert(solution.points[p]->id());
    if (!solution.points[p]->isBad()) solution.points[p]->setPosition(solution.p_w_after[p]);
  }
  for (const std::shared_ptr<map::MapPoint>& point : map.mapPoints()) {
    if (point->isBad() || optimised.count(point->id()) > 0) continue;
    const auto it = correction.find(point->referenceKeyFrame());
    if (it != correction.end()) point->setPosition(it->second * point->p_w());
  }
  map.bumpVersion();
  const GlobalBaResult& result = solution.result;
  log::info("global BA: ", result.keyframes, " keyframes, ", result.points, " points, ", result.observations,
            " observations, ", result.inertial_links, " inertial links, ", result.outliers, " outliers, chi2 ",
            result.initial_chi2, " -> ", result.final_chi2, "; ", propagated, " newer keyframes moved with their parents");
  return propagated;
}

GlobalBaResult runGlobalBundleAdjustment(map::Map& map, const GlobalBaOptions& options) {
  const GlobalBaSolution solution = optimizeGlobalBundleAdjustment(map, options);
  applyGlobalBundleAdjustment(map, solution);
  return solution.result;
}

}  // namespace ltlo::loop
