#include "local_window_ba.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "ltlo/core/log.h"
#include "ltlo/optim/bundle_adjust.h"

namespace ltlo::mapping {

namespace {

struct WindowKeyFrame {
  std::shared_ptr<map::KeyFrame> kf;
  bool fixed = false;
  std::vector<double> gamma;  ///< the keyframe's cluster scores (copied once)
};

int baId(map::KeyFrameId id) { return static_cast<int>(id.value); }
int baId(map::MapPointId id) { return static_cast<int>(id.value); }

double gammaOfKeypoint(const WindowKeyFrame& entry, int i) {
  const int cluster = entry.kf->clusterOf(i);
  return cluster >= 0 && cluster < static_cast<int>(entry.gamma.size()) ? entry.gamma[static_cast<std::size_t>(cluster)]
                                                                        : 1.0;
}

bool usable(const std::shared_ptr<map::KeyFrame>& kf) { return kf != nullptr && !kf->isBad(); }

}  // namespace

WindowBaStats localWindowBundleAdjust(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf,
                                      const WindowBaOptions& options, const std::vector<float>& level_sigma2) {
  WindowBaStats stats;
  if (!usable(kf)) return stats;

  // ---- the optimised window (and, inertial, the fixed keyframe before it) ----
  std::vector<WindowKeyFrame> keyframes;
  std::unordered_map<map::KeyFrameId, std::size_t> index_of;
  auto add_keyframe = [&](const std::shared_ptr<map::KeyFrame>& k, bool fixed) {
    if (!index_of.emplace(k->id(), keyframes.size()).second) return;
    keyframes.push_back({k, fixed, k->gamma()});
  };
  optim::LocalBaProblem problem;
  std::vector<std::pair<map::KeyFrameId, map::KeyFrameId>> links;  // i -> j, pim of j
  const std::size_t window_size = static_cast<std::size_t>(std::max(1, options.window_size));
  add_keyframe(kf, false);
  if (options.inertial) {
    std::shared_ptr<map::KeyFrame> newer = kf;
    while (true) {
      const std::shared_ptr<map::KeyFrame> older = map.keyFrame(newer->previousKeyFrame());
      const std::optional<imu::Preintegrated> pim = newer->imuFromPrevious();
      if (!usable(older) || !pim) break;
      const bool border = keyframes.size() >= window_size;
      add_keyframe(older, border);
      problem.inertial.push_back({baId(older->id()), baId(newer->id()),
                                  std::make_shared<const imu::Preintegrated>(*pim)});
      if (border) break;
      newer = older;
    }
  } else {
    for (const map::KeyFrameId id : kf->bestCovisibles(window_size - 1)) {
      const std::shared_ptr<map::KeyFrame> other = map.keyFrame(id);
      if (usable(other)) add_keyframe(other, false);
    }
  }
  const std::vector<map::KeyFrameId> origins = map.originKeyFrames();
  for (WindowKeyFrame& entry : keyframes) {
    if (std::find(origins.begin(), origins.end(), entry.kf->id()) != origins.end()) entry.fixed = true;
  }
  const std::size_t window_end = keyframes.size();

  // ---- points seen by the window, and the other keyframes seeing them (fixed) ----
  std::vector<std::shared_ptr<map::MapPoint>> points;
  std::unordered_set<map::MapPointId> point_seen;
  std::unordered_map<map::KeyFrameId, int> fixed_counts;
  for (std::size_t k = 0; k < window_end; ++k) {
    for (const map::MapPointId id : keyframes[k].kf->mapPoints()) {
      if (!id.valid() || !point_seen.insert(id).second) continue;
      const std::shared_ptr<map::MapPoint> point = map.mapPoint(id);
      if (!point || point->isBad() || point->beta() < options.min_point_beta) continue;
      points.push_back(point);
      for (const auto& [observer, index] : point->observations()) {
        if (index_of.count(observer) == 0) ++fixed_counts[observer];
      }
    }
  }
  std::vector<std::pair<int, map::KeyFrameId>> by_count;
  for (const auto& [id, count] : fixed_counts) by_count.emplace_back(-count, id);
  std::sort(by_count.begin(), by_count.end());
  for (const auto& [negative_count, id] : by_count) {
    if (keyframes.size() - window_end >= options.max_fixed_keyframes) break;
    const std::shared_ptr<map::KeyFrame> other = map.keyFrame(id);
    if (usable(other)) add_keyframe(other, true);
  }
  // Gauge: without any fixed keyframe, hold the oldest of the window.
  if (std::none_of(keyframes.begin(), keyframes.end(), [](const WindowKeyFrame& e) { return e.fixed; })) {
    std::min_element(keyframes.begin(), keyframes.end(), [](const WindowKeyFrame& a, const WindowKeyFrame& b) {
      return a.kf->t_s() < b.kf->t_s();
    })->fixed = true;
  }

  // ---- the problem ----
  problem.model.camera = kf->camera();
  problem.model.T_c_x = kf->T_b_c().inverse();
  problem.model.bf_px_m = options.bf_px_m;
  problem.g_w = options.g_w;
  problem.lambda_imu = options.lambda_imu;
  for (const WindowKeyFrame& entry : keyframes) {
    optim::BaKeyFrame ba;
    ba.id = baId(entry.kf->id());
    ba.T_w_b = entry.kf->T_w_b();
    ba.v_w_b = entry.kf->v_w_b();
    ba.bias = entry.kf->bias();
    ba.fixed = entry.fixed;
    problem.keyframes.push_back(ba);
  }
  struct ObservationRef {
    std::size_t keyframe;
    std::size_t point;
    int index;
  };
  std::vector<ObservationRef> refs;
  std::vector<std::shared_ptr<map::MapPoint>> problem_points;
  for (const std::shared_ptr<map::MapPoint>& point : points) {
    const std::size_t point_index = problem_points.size();
    const double beta = point->beta();
    std::vector<optim::BaObservation> observations;
    std::vector<ObservationRef> point_refs;
    bool has_depth = false;
    for (const auto& [observer, index] : point->observations()) {
      const auto it = index_of.find(observer);
      if (it == index_of.end()) continue;
      const WindowKeyFrame& entry = keyframes[it->second];
      if (index < 0 || index >= entry.kf->numKeypoints()) continue;
      const features::Keypoint& kp = entry.kf->keypoints()[static_cast<std::size_t>(index)];
      optim::BaObservation obs;
      obs.keyframe_id = baId(observer);
      obs.point_id = baId(point->id());
      obs.uv = Vec2(kp.x_px, kp.y_px);
      obs.depth_m = entry.kf->depth_m(index);
      obs.sigma_px = std::sqrt(static_cast<double>(
          level_sigma2[std::min<std::size_t>(static_cast<std::size_t>(kp.octave), level_sigma2.size() - 1)]));
      obs.static_weight = beta * gammaOfKeypoint(entry, index);
      has_depth = has_depth || obs.depth_m > 0.0;
      observations.push_back(obs);
      point_refs.push_back({it->second, point_index, index});
    }
    // A point needs depth or two views to be constrained.
    if (observations.empty() || (!has_depth && observations.size() < 2)) continue;
    problem.points.push_back({baId(point->id()), point->p_w()});
    problem_points.push_back(point);
    problem.observations.insert(problem.observations.end(), observations.begin(), observations.end());
    refs.insert(refs.end(), point_refs.begin(), point_refs.end());
  }
  stats.points = static_cast<int>(problem.points.size());
  stats.observations = static_cast<int>(problem.observations.size());
  stats.inertial_links = static_cast<int>(problem.inertial.size());
  for (const WindowKeyFrame& entry : keyframes) (entry.fixed ? stats.fixed_keyframes : stats.optimised_keyframes)++;
  if (stats.optimised_keyframes == 0 || problem.observations.empty()) return stats;

  optim::LocalBaOptions ba_options;
  ba_options.iterations = options.iterations;
  ba_options.num_threads = options.num_threads;
  ba_options.stop_flag = options.stop_flag;
  const optim::LocalBaResult result = optim::localBundleAdjust(problem, ba_options);
  stats.aborted = options.stop_flag != nullptr && options.stop_flag->load();
  stats.final_chi2 = result.summary.final_chi2;

  // ---- write back (skipping what went bad meanwhile) ----
  std::unordered_set<int> with_inertial;
  for (const optim::BaInertialLink& link : problem.inertial) {
    with_inertial.insert(link.keyframe_i);
    with_inertial.insert(link.keyframe_j);
  }
  for (std::size_t k = 0; k < keyframes.size(); ++k) {
    if (keyframes[k].fixed || keyframes[k].kf->isBad()) continue;
    const optim::BaKeyFrame& out = result.keyframes[k];
    if (!out.T_w_b.translation().allFinite()) continue;
    keyframes[k].kf->setPose_T_w_b(out.T_w_b);
    if (with_inertial.count(out.id) > 0) {
      keyframes[k].kf->setVelocity(out.v_w_b);
      keyframes[k].kf->setBias(out.bias);
    }
  }
  for (std::size_t m = 0; m < problem_points.size(); ++m) {
    if (!problem_points[m]->isBad() && result.points[m].p_w.allFinite()) {
      problem_points[m]->setPosition(result.points[m].p_w);
    }
  }
  for (std::size_t o = 0; o < refs.size(); ++o) {
    if (result.inliers[o]) continue;
    const ObservationRef& ref = refs[o];
    map::KeyFrame& observer = *keyframes[ref.keyframe].kf;
    const std::shared_ptr<map::MapPoint>& point = problem_points[ref.point];
    if (observer.isBad() || observer.mapPoint(ref.index) != point->id()) continue;
    map.eraseObservation(observer, ref.index);
    ++stats.outliers_erased;
    if (point->numObservations() == 0) map.eraseMapPoint(point->id());
  }
  return stats;
}

}  // namespace ltlo::mapping
