#include "ltlo/system/carried_stretch.h"

#include <algorithm>

#include "ltlo/core/log.h"
#include "ltlo/system/carried_bridge.h"

namespace ltlo::system {

double carriedCorrectionShare(double tau, double duration_s, double velocity_sigma_m_s, double acc_sigma_m_s2) {
  tau = std::clamp(tau, 0.0, 1.0);
  const double velocity_weight = velocity_sigma_m_s * velocity_sigma_m_s;
  const double acceleration_weight = 0.25 * acc_sigma_m_s2 * acc_sigma_m_s2 * duration_s * duration_s;
  const double total = velocity_weight + acceleration_weight;
  if (total <= 0.0) return tau;  // no error model: the correction grows linearly
  return (velocity_weight * tau + acceleration_weight * tau * tau) / total;
}

namespace {

/// The blend: frame k of the stretch [begin, end) moves by share(tau_k) of the anchored frame's
/// position difference and turns by share(tau_k) of its rotation difference.
void blendStretch(std::vector<CarriedSample>& samples, std::size_t begin, std::size_t end, double velocity_sigma_m_s,
                  double acc_sigma_m_s2) {
  const double t_start_s = samples[begin - 1].t_s;
  const double duration_s = samples[end].t_s - t_start_s;
  const SE3& anchored = samples[end].T_w_c;
  const SE3& predicted = *samples[end].T_w_c_dead_reckoned;
  const Vec3 dp_w = anchored.translation() - predicted.translation();
  const Vec3 dphi_w = so3Log(anchored.rotationMatrix() * predicted.rotationMatrix().transpose());
  for (std::size_t k = begin; k < end; ++k) {
    const double share = carriedCorrectionShare((samples[k].t_s - t_start_s) / duration_s, duration_s,
                                                velocity_sigma_m_s, acc_sigma_m_s2);
    const SE3& T_w_c = samples[k].T_w_c;
    samples[k].T_w_c = SE3(so3Exp(share * dphi_w) * T_w_c.rotationMatrix(), T_w_c.translation() + share * dp_w);
  }
  log::debug("carried stretch ", samples[begin].t_s, " - ", samples[end - 1].t_s, " s: smoothed, end correction ",
             dp_w.norm(), " m / ", dphi_w.norm() * 180.0 / M_PI, " deg");
}

}  // namespace

int smoothCarriedStretches(std::vector<CarriedSample>& samples, double velocity_sigma_m_s, double acc_sigma_m_s2) {
  CarriedCorrectionOptions options;
  options.bridge = false;
  options.velocity_sigma_m_s = velocity_sigma_m_s;
  options.acc_bias_sigma_m_s2 = acc_sigma_m_s2;
  return correctCarriedStretches(samples, options).blended;
}

CarriedCorrectionCounts correctCarriedStretches(std::vector<CarriedSample>& samples,
                                                const CarriedCorrectionOptions& options) {
  CarriedCorrectionCounts counts;
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
    if (samples[end].t_s - samples[begin - 1].t_s <= 0.0) continue;
    if (options.bridge) {
      CarriedBridgeOptions bridge;
      bridge.velocity_sigma_m_s = options.velocity_sigma_m_s;
      bridge.acc_bias_sigma_m_s2 = options.acc_bias_sigma_m_s2;
      bridge.gyro_bias_sigma_rad_s = options.gyro_bias_sigma_rad_s;
      bridge.margin_s = options.margin_s;
      if (const std::optional<CarriedBridgeResult> result = bridgeCarriedStretch(samples, begin, end, bridge)) {
        const SE3 moved_end = samples[end - 1].T_w_c.inverse() * result->T_w_c.back();
        for (std::size_t k = begin; k < end; ++k) samples[k].T_w_c = result->T_w_c[k - begin];
        log::debug("carried stretch ", samples[begin].t_s, " - ", samples[end - 1].t_s, " s: bridged, ",
                   result->margin_before, " + ", result->margin_after, " margin frames, chi2 ", result->initial_chi2,
                   " -> ", result->final_chi2, " in ", result->iterations, " iterations, last frame moved ",
                   moved_end.translation().norm(), " m, b_g ", result->bias.b_g.transpose(), " b_a ",
                   result->bias.b_a.transpose());
        ++counts.bridged;
        continue;
      }
      log::debug("carried stretch ", samples[begin].t_s, " - ", samples[end - 1].t_s,
                 " s: no inertial bridge (IMU data incomplete or no solution), blended");
    }
    blendStretch(samples, begin, end, options.velocity_sigma_m_s, options.acc_bias_sigma_m_s2);
    ++counts.blended;
  }
  return counts;
}

std::vector<std::pair<std::size_t, std::shared_ptr<const CarriedImu>>> CarriedImuRetention::add(
    std::size_t index, double t_s, bool carried, std::uint64_t map, std::shared_ptr<const CarriedImu> imu) {
  std::vector<std::pair<std::size_t, std::shared_ptr<const CarriedImu>>> kept;
  if (carried) {
    if (!state_.stretch_open) {
      state_.stretch_open = true;
      state_.stretch_map = state_.recent.empty() ? map : state_.recent.back().map;  // the last tracked frame's
    }
    for (Pending& pending : state_.recent) kept.emplace_back(pending.index, std::move(pending.imu));
    state_.recent.clear();
    kept.emplace_back(index, std::move(imu));
    state_.last_carried_t_s = t_s;
    state_.keep_until_s = t_s + margin_s_;
    return kept;
  }
  // A frame tracked in another map soon after a stretch may lie in a floating map: part of it.
  if (state_.stretch_open && map != state_.stretch_map && t_s - state_.last_carried_t_s <= kFloatingSpan_s) {
    state_.keep_until_s = t_s + margin_s_;
  }
  if (t_s <= state_.keep_until_s) {
    kept.emplace_back(index, std::move(imu));
    return kept;
  }
  state_.stretch_open = false;
  state_.recent.push_back(Pending{index, t_s, map, std::move(imu)});
  while (!state_.recent.empty() && t_s - state_.recent.front().t_s > margin_s_) state_.recent.pop_front();
  return kept;
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
