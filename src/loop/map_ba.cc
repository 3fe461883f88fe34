#include "map_ba.h"

#include <algorithm>
#include <unordered_map>
#include <unordered_set>

#include "ltlo/core/assert.h"

namespace ltlo::loop {

namespace {

bool usable(const std::shared_ptr<map::KeyFrame>& kf) { return kf != nullptr && !kf->isBad(); }

enum class Role { kOptimised, kGauge, kFixed };

struct Entry {
  std::shared_ptr<map::KeyFrame> kf;
  Role role = Role::kOptimised;
  std::vector<double> gamma;  ///< the keyframe's cluster scores (copied once)
};

double gammaOf(const Entry& entry, int keypoint) {
  const int cluster = entry.kf->clusterOf(keypoint);
  return cluster >= 0 && cluster < static_cast<int>(entry.gamma.size()) ? entry.gamma[static_cast<std::size_t>(cluster)]
                                                                        : 1.0;
}

}  // namespace

MapBaProblem buildMapBa(const map::Map& map, const MapBaSelection& selection, const MapBaOptions& options) {
  MapBaProblem out;
  std::vector<Entry> entries;
  std::unordered_map<map::KeyFrameId, std::size_t> index_of;
  auto add = [&](const std::shared_ptr<map::KeyFrame>& kf, Role role) {
    if (!usable(kf)) return;
    if (role == Role::kOptimised && kf->isAnchor()) role = Role::kGauge;  // a loaded atlas's pose is held
    const auto [it, inserted] = index_of.emplace(kf->id(), entries.size());
    if (inserted) {
      entries.push_back({kf, role, kf->gamma()});
    } else if (role == Role::kFixed || (role == Role::kGauge && entries[it->second].role == Role::kOptimised)) {
      entries[it->second].role = role;  // holding wins
    }
  };
  for (const std::shared_ptr<map::KeyFrame>& kf : selection.optimised) add(kf, Role::kOptimised);
  for (const std::shared_ptr<map::KeyFrame>& kf : selection.gauge) add(kf, Role::kGauge);
  for (const std::shared_ptr<map::KeyFrame>& kf : selection.fixed) add(kf, Role::kFixed);
  const std::size_t selected = entries.size();

  // Points of the optimised keyframes; their other observers, most shared first, held.
  std::vector<std::shared_ptr<map::MapPoint>> candidates;
  std::unordered_set<map::MapPointId> seen;
  std::unordered_map<map::KeyFrameId, int> observer_counts;
  for (std::size_t k = 0; k < selected; ++k) {
    if (entries[k].role != Role::kOptimised) continue;
    for (const map::MapPointId id : entries[k].kf->mapPoints()) {
      if (!id.valid() || !seen.insert(id).second) continue;
      const std::shared_ptr<map::MapPoint> point = map.mapPoint(id);
      if (!point || point->isBad() || point->beta() < options.min_point_beta) continue;
      candidates.push_back(point);
      for (const auto& [observer, index] : point->observations()) {
        if (index_of.count(observer) == 0) ++observer_counts[observer];
      }
    }
  }
  std::vector<std::pair<int, map::KeyFrameId>> by_count;
  for (const auto& [id, count] : observer_counts) by_count.emplace_back(-count, id);
  std::sort(by_count.begin(), by_count.end());
  for (const auto& [negative_count, id] : by_count) {
    if (entries.size() - selected >= options.max_fixed_observers) break;
    add(map.keyFrame(id), Role::kFixed);
  }
  const bool any_held = std::any_of(entries.begin(), entries.end(), [](const Entry& e) { return e.role != Role::kOptimised; });
  if (!any_held && !entries.empty()) {
    std::min_element(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
      return a.kf->t_s() < b.kf->t_s();
    })->role = Role::kGauge;
  }

  optim::LocalBaProblem& problem = out.problem;
  if (entries.empty()) return out;
  problem.model.camera = entries.front().kf->camera();
  problem.model.T_c_x = entries.front().kf->T_b_c().inverse();
  problem.model.bf_px_m = options.bf_px_m;
  problem.lambda_imu = options.lambda_imu;
  if (options.g_w) problem.g_w = *options.g_w;
  for (std::size_t k = 0; k < entries.size(); ++k) {
    const Entry& entry = entries[k];
    optim::BaKeyFrame v;
    v.id = static_cast<int>(k);
    v.T_w_b = entry.kf->T_w_b();
    v.v_w_b = entry.kf->v_w_b();
    v.bias = entry.kf->bias();
    v.fixed = entry.role != Role::kOptimised;
    v.fixed_pose_only = entry.role == Role::kGauge && options.g_w.has_value();
    problem.keyframes.push_back(v);
    out.keyframes.push_back(entry.kf);
    (v.fixed ? out.fixed_keyframes : out.optimised_keyframes)++;
  }

  if (options.g_w) {
    for (std::size_t k = 0; k < entries.size(); ++k) {
      const auto previous = index_of.find(entries[k].kf->previousKeyFrame());
      if (previous == index_of.end()) continue;
      if (entries[k].role != Role::kOptimised && entries[previous->second].role != Role::kOptimised) continue;
      std::optional<imu::Preintegrated> pim = entries[k].kf->imuFromPrevious();
      if (!pim || pim->dt_s() <= 0.0) continue;
      problem.inertial.push_back({static_cast<int>(previous->second), static_cast<int>(k),
                                  std::make_shared<const imu::Preintegrated>(std::move(*pim))});
    }
  }

  for (const std::shared_ptr<map::MapPoint>& point : candidates) {
    const int point_id = static_cast<int>(out.points.size());
    const double beta = point->beta();
    std::vector<optim::BaObservation> observations;
    for (const auto& [observer, index] : point->observations()) {
      const auto it = index_of.find(observer);
      if (it == index_of.end()) continue;
      const Entry& entry = entries[it->second];
      if (index < 0 || index >= entry.kf->numKeypoints()) continue;
      const features::Keypoint& kp = entry.kf->keypoints()[static_cast<std::size_t>(index)];
      const std::vector<float>& scales = entry.kf->scaleFactors();
      optim::BaObservation obs;
      obs.keyframe_id = static_cast<int>(it->second);
      obs.point_id = point_id;
      obs.uv = Vec2(kp.x_px, kp.y_px);
      obs.depth_m = entry.kf->depth_m(index);
      obs.sigma_px = scales.empty() ? 1.0
                                    : scales[std::min<std::size_t>(static_cast<std::size_t>(std::max(kp.octave, 0)),
                                                                   scales.size() - 1)];
      obs.static_weight = beta * gammaOf(entry, index);
      observations.push_back(obs);
    }
    if (observations.size() < 2) continue;
    problem.points.push_back(optim::BaPoint{point_id, point->p_w()});
    out.points.push_back(point);
    problem.observations.insert(problem.observations.end(), observations.begin(), observations.end());
  }
  if (options.g_w && options.visual_variance_estimation && !problem.inertial.empty()) {
    problem.inertial_information_scale = optim::inertialInformationScale(problem);
  }
  return out;
}

std::vector<bool> inertialKeyFrames(const MapBaProblem& problem) {
  std::vector<bool> inertial(problem.keyframes.size(), false);
  for (const optim::BaInertialLink& link : problem.problem.inertial) {
    inertial[static_cast<std::size_t>(link.keyframe_i)] = true;
    inertial[static_cast<std::size_t>(link.keyframe_j)] = true;
  }
  return inertial;
}

}  // namespace ltlo::loop
