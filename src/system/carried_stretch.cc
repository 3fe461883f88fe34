#include "ltlo/system/carried_stretch.h"

#include <algorithm>

#include "ltlo/core/log.h"

namespace ltlo::system {

double carriedCorrectionShare(double tau, double duration_s, double velocity_sigma_m_s, double acc_sigma_m_s2) {
  tau = std::clamp(tau, 0.0, 1.0);
  const double velocity_weight = velocity_sigma_m_s * velocity_sigma_m_s;
  const double acceleration_weight = 0.25 * acc_sigma_m_s2 * acc_sigma_m_s2 * duration_s * duration_s;
  const double total = velocity_weight + acceleration_weight;
  if (total <= 0.0) return tau;  // no error model: the correction grows linearly
  return (velocity_weight * tau + acceleration_weight * tau * tau) / total;
}

int smoothCarriedStretches(std::vector<CarriedSample>& samples, double velocity_sigma_m_s, double acc_sigma_m_s2) {
  int corrected = 0;
  std::size_t i = 0;
  while (i < samples.size()) {
    if (!samples[i].carried) {
      ++i;
      continue;
    }
    const std::size_t begin = i;
    while (i < samples.size() && samples[i].carried) ++i;
    const std::size_t end = i;  // the anchored sample after the stretch, if any
    if (begin == 0 || end == samples.size() || !samples[end].T_w_c_dead_reckoned) {
      log::debug("carried stretch ", samples[begin].t_s, " - ", samples[end - 1].t_s, " s: not smoothed (",
                 begin == 0 ? "at the start" : end == samples.size() ? "at the end" : "its end not comparable", ")");
      continue;
    }
    const double t_start_s = samples[begin - 1].t_s;
    const double duration_s = samples[end].t_s - t_start_s;
    if (duration_s <= 0.0) continue;
    const SE3& anchored = samples[end].T_w_c;
    const SE3& predicted = *samples[end].T_w_c_dead_reckoned;
    const Vec3 dp_w = anchored.translation() - predicted.translation();
    const Vec3 dphi_w = so3Log(anchored.rotationMatrix() * predicted.rotationMatrix().transpose());
    for (std::size_t k = begin; k < end; ++k) {
      const double share =
          carriedCorrectionShare((samples[k].t_s - t_start_s) / duration_s, duration_s, velocity_sigma_m_s,
                                 acc_sigma_m_s2);
      const SE3& T_w_c = samples[k].T_w_c;
      samples[k].T_w_c = SE3(so3Exp(share * dphi_w) * T_w_c.rotationMatrix(), T_w_c.translation() + share * dp_w);
    }
    log::debug("carried stretch ", samples[begin].t_s, " - ", samples[end - 1].t_s, " s: smoothed, end correction ",
               dp_w.norm(), " m / ", dphi_w.norm() * 180.0 / M_PI, " deg");
    ++corrected;
  }
  return corrected;
}

std::unordered_map<map::MapId, map::MapId> floatingMapWorlds(const std::unordered_map<map::MapId, MapFrameSpan>& maps,
                                                            double max_span_s, int max_depth) {
  const auto floats = [&](map::MapId id) {
    const auto it = maps.find(id);
    return it != maps.end() && it->second.origin_parent && it->second.last_t_s - it->second.first_t_s <= max_span_s;
  };
  std::unordered_map<map::MapId, map::MapId> worlds;
  for (const auto& [id, span] : maps) {
    if (!floats(id)) continue;
    map::MapId world = *span.origin_parent;
    for (int depth = 1; depth < max_depth && floats(world) && world != id; ++depth) {
      world = *maps.at(world).origin_parent;
    }
    if (world != id) worlds.emplace(id, world);
  }
  return worlds;
}

}  // namespace ltlo::system
