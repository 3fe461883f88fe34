#include "ltlo/loop/global_ba.h"

#include <unordered_map>
#include <unordered_set>

#include "ltlo/core/log.h"
#include "ltlo/optim/bundle_adjust.h"

namespace ltlo::loop {

GlobalBaResult runGlobalBundleAdjustment(map::Map& map, const GlobalBaOptions& options) {
  GlobalBaResult result;
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
  for (const std::shared_ptr<map::KeyFrame>& kf : map.keyFrames()) {
    if (!kf->isBad()) keyframes.push_back(kf);
  }
  if (keyframes.size() < 2) return result;

  optim::LocalBaProblem problem;
  const map::KeyFrame& first = *keyframes.front();
  problem.model.camera = first.camera();
  problem.model.T_c_x = first.T_b_c().inverse();
  problem.model.bf_px_m = first.camera().K()(0, 0) * options.virtual_baseline_m;

  const std::vector<map::KeyFrameId> origins = map.originKeyFrames();
  const std::unordered_set<map::KeyFrameId> fixed(origins.begin(), origins.end());
  std::unordered_map<map::KeyFrameId, int> kf_index;
  for (const std::shared_ptr<map::KeyFrame>& kf : keyframes) {
    optim::BaKeyFrame v;
    v.id = static_cast<int>(problem.keyframes.size());
    v.T_w_b = kf->T_w_b();
    v.fixed = fixed.count(kf->id()) > 0;
    kf_index[kf->id()] = v.id;
    problem.keyframes.push_back(v);
  }
  bool any_fixed = false;
  for (const optim::BaKeyFrame& v : problem.keyframes) any_fixed = any_fixed || v.fixed;
  if (!any_fixed) problem.keyframes.front().fixed = true;

  std::vector<std::shared_ptr<map::MapPoint>> points;
  for (const std::shared_ptr<map::MapPoint>& point : map.mapPoints()) {
    if (point->isBad()) continue;
    std::vector<optim::BaObservation> observations;
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
  if (points.empty()) return result;

  optim::LocalBaOptions ba_options;
  ba_options.iterations = options.iterations;
  ba_options.num_threads = options.num_threads;
  ba_options.stop_flag = options.stop_flag;
  const optim::LocalBaResult solved = optim::localBundleAdjust(problem, ba_options);
  if (options.stop_flag != nullptr && options.stop_flag->load()) return result;  // discarded
  for (std::size_t k = 0; k < keyframes.size(); ++k) keyframes[k]->setPose_T_w_b(solved.keyframes[k].T_w_b);
  for (std::size_t p = 0; p < points.size(); ++p) {
    if (!points[p]->isBad()) points[p]->setPosition(solved.points[p].p_w);
  }
  for (const bool inlier : solved.inliers) result.outliers += inlier ? 0 : 1;
  result.initial_chi2 = solved.summary.initial_chi2;
  result.final_chi2 = solved.summary.final_chi2;
  map.bumpVersion();
  log::info("global BA: ", result.keyframes, " keyframes, ", result.points, " points, ", result.observations,
            " observations, ", result.outliers, " outliers, chi2 ", result.initial_chi2, " -> ", result.final_chi2);
  return result;
}

}  // namespace ltlo::loop
