#include "ltlo/loop/global_ba.h"

#include <unordered_map>
#include <unordered_set>

#include "ltlo/core/log.h"
#include "ltlo/optim/bundle_adjust.h"

namespace ltlo::loop {

GlobalBaSolution optimizeGlobalBundleAdjustment(const map::Map& map, const GlobalBaOptions& options) {
  GlobalBaSolution solution;
  GlobalBaResult& result = solution.result;
  std::vector<std::shared_ptr<map::KeyFrame>>& keyframes = solution.keyframes;
  for (const std::shared_ptr<map::KeyFrame>& kf : map.keyFrames()) {
    if (!kf->isBad()) keyframes.push_back(kf);
  }
  if (keyframes.size() < 2) return solution;

  optim::LocalBaProblem problem;
  const map::KeyFrame& first = *keyframes.front();
  problem.model.camera = first.camera();
  problem.model.T_c_x = first.T_b_c().inverse();
  problem.model.bf_px_m = first.camera().K()(0, 0) * options.virtual_baseline_m;

  const std::vector<map::KeyFrameId> origins = map.originKeyFrames();
  const std::unordered_set<map::KeyFrameId> fixed(origins.begin(), origins.end());
  std::unordered_map<map::KeyFrameId, int> kf_index;
  std::vector<std::vector<double>> gamma_of_kf;  // the keyframes' current static scores (Gamma)
  for (const std::shared_ptr<map::KeyFrame>& kf : keyframes) {
    gamma_of_kf.push_back(kf->gamma());
    optim::BaKeyFrame v;
    v.id = static_cast<int>(problem.keyframes.size());
    v.T_w_b = kf->T_w_b();
    solution.T_w_b_before.push_back(v.T_w_b);
    v.fixed = fixed.count(kf->id()) > 0;
    kf_index[kf->id()] = v.id;
    problem.keyframes.push_back(v);
  }
  bool any_fixed = false;
  for (const optim::BaKeyFrame& v : problem.keyframes) any_fixed = any_fixed || v.fixed;
  if (!any_fixed) problem.keyframes.front().fixed = true;

  std::vector<std::shared_ptr<map::MapPoint>>& points = solution.points;
  for (const std::shared_ptr<map::MapPoint>& point : map.mapPoints()) {
    if (point->isBad()) continue;
    std::vector<optim::BaObservation> observations;
    const double beta = point->beta();
    for (const auto& [kf_id, index] : point->observations()) {
      const auto it = kf_index.find(kf_id);
      if (it == kf_index.end()) continue;
      const map::KeyFrame& kf = *keyframes[static_cast<std::size_t>(it->second)];
      const features::Keypoint& kp = kf.keypoints()[static_cast<std::size_t>(index)];
      optim::BaObservation obs;
      obs.keyframe_id = it->second;
      obs.point_id = static_cast<int>(points.size());
      obs.uv = Vec2(kp.x_px, kp.y_px);
      obs.depth_m = kf.depth_m(index);
      obs.sigma_px = kf.scaleFactors()[static_cast<std::size_t>(kp.octave)];
      // beta * gamma weighs the observation as in the local robust VIBA (Eq. 53); weight 0 leaves the system.
      const std::vector<double>& gamma = gamma_of_kf[static_cast<std::size_t>(it->second)];
      const int cluster = kf.clusterOf(index);
      obs.static_weight =
          beta * (cluster >= 0 && cluster < static_cast<int>(gamma.size()) ? gamma[static_cast<std::size_t>(cluster)] : 1.0);
      observations.push_back(obs);
    }
    if (observations.size() < 2) continue;
    problem.points.push_back(optim::BaPoint{static_cast<int>(points.size()), point->p_w()});
    points.push_back(point);
    problem.observations.insert(problem.observations.end(), observations.begin(), observations.end());
  }
  result.keyframes = static_cast<int>(keyframes.size());
  result.points = static_cast<int>(points.size());
  result.observations = static_cast<int>(problem.observations.size());
  if (points.empty()) return solution;

  optim::LocalBaOptions ba_options;
  ba_options.iterations = options.iterations;
  ba_options.num_threads = options.num_threads;
  ba_options.stop_flag = options.stop_flag;
  const optim::LocalBaResult solved = optim::localBundleAdjust(problem, ba_options);
  if (options.stop_flag != nullptr && options.stop_flag->load()) return solution;  // discarded (invalid)
  for (const optim::BaKeyFrame& v : solved.keyframes) solution.T_w_b_after.push_back(v.T_w_b);
  for (const optim::BaPoint& p : solved.points) solution.p_w_after.push_back(p.p_w);
  for (const bool inlier : solved.inliers) result.outliers += inlier ? 0 : 1;
  result.initial_chi2 = solved.summary.initial_chi2;
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
    correction[kf->id()] = parent->second;
    ++propagated;
  }
  for (std::size_t k = 0; k < solution.keyframes.size(); ++k) {
    if (!solution.keyframes[k]->isBad()) solution.keyframes[k]->setPose_T_w_b(solution.T_w_b_after[k]);
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
            " observations, ", result.outliers, " outliers, chi2 ", result.initial_chi2, " -> ", result.final_chi2,
            "; ", propagated, " newer keyframes moved with their parents");
  return propagated;
}

GlobalBaResult runGlobalBundleAdjustment(map::Map& map, const GlobalBaOptions& options) {
  const GlobalBaSolution solution = optimizeGlobalBundleAdjustment(map, options);
  applyGlobalBundleAdjustment(map, solution);
  return solution.result;
}

}  // namespace ltlo::loop
