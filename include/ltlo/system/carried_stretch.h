#pragma once
/// The output poses of IMU-carried stretches: frames vision could not track (black, or covered by
/// an occluder), posed by the IMU's dead reckoning from the last tracked frame. Once vision anchors
/// the frame after such a stretch, the map tells where that frame really is; the difference to where
/// the dead reckoning put it is the stretch's accumulated prediction error, and it is spread over the
/// stretch's frames in the shape the IMU's error model predicts (trajectory output only: the live
/// tracking and the map are unchanged).
#include <optional>
#include <unordered_map>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/map/ids.h"

namespace ltlo::system {

/// One output pose as the smoothing of carried stretches sees it.
struct CarriedSample {
  double t_s = 0.0;
  SE3 T_w_c;
  /// posed by the IMU's prediction alone (not tracked by vision)
  bool carried = false;
  /// Only for the first frame anchored by vision after a carried stretch: its pose as the
  /// stretch's dead reckoning put it, expressed in today's world frame (through the keyframe the
  /// stretch was predicted from). Absent when not comparable (e.g. the two lie in different maps).
  std::optional<SE3> T_w_c_dead_reckoned;
};

/// Share in [0, 1] of a stretch's end correction applied at tau = (t - t_start) / duration. An
/// IMU-only prediction drifts by dp(t) = dv t + 0.5 da t^2 (dv the velocity error at the start,
/// da the constant world-acceleration error of the accelerometer bias and the gravity direction);
/// given the end error dp(T), the least-squares split with dv ~ sigma_v and da ~ sigma_a is
/// dv = l sigma_v^2 T, da = l sigma_a^2 T^2 / 2, hence
/// share(tau) = (sigma_v^2 tau + sigma_a^2 T^2 tau^2 / 4) / (sigma_v^2 + sigma_a^2 T^2 / 4).
double carriedCorrectionShare(double tau, double duration_s, double velocity_sigma_m_s, double acc_sigma_m_s2);

/// Corrects every carried stretch that has a sample before it and is followed by a sample with
/// T_w_c_dead_reckoned: frame k of the stretch moves by share(tau_k) of the end's position
/// difference and is rotated by share(tau_k) of its rotation difference (about its own centre),
/// with the stretch running from the last sample before it to the anchored one. Returns the number
/// of stretches corrected.
int smoothCarriedStretches(std::vector<CarriedSample>& samples, double velocity_sigma_m_s, double acc_sigma_m_s2);

/// A map holding frames at the end of a run: its frames' time span and, when it was started at the
/// IMU's prediction (map::MapOrigin) and never merged, its origin's parent (resolved through
/// merges).
struct MapFrameSpan {
  double first_t_s = 0.0;
  double last_t_s = 0.0;
  std::optional<map::MapId> origin_parent;
};

/// Floating maps: started at the IMU's prediction, never merged, frames spanning at most
/// max_span_s. Their coordinates are the parent's world as the dead reckoning placed them, so their
/// frames belong to the IMU-carried stretch around them, and a frame anchored after it in the
/// parent's map ends that stretch. A floating map's parent that floats itself stands for its own
/// parent (at most max_depth steps). Returns floating map -> the map whose world it stands in.
std::unordered_map<map::MapId, map::MapId> floatingMapWorlds(const std::unordered_map<map::MapId, MapFrameSpan>& maps,
                                                            double max_span_s, int max_depth);

}  // namespace ltlo::system
