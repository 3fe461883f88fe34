#pragma once
/// The output poses of IMU-carried stretches: frames vision could not track (black, or covered by
/// an occluder), posed by the IMU's dead reckoning from the last tracked frame. Once vision anchors
/// the frame after such a stretch, the map tells where that frame really is. Two corrections
/// (trajectory output only: the live tracking and the map are unchanged):
///   - the inertial bridge (system/carried_bridge.h): the stretch's states solved again from its
///     own IMU data between the two anchored ends, with the biases free about the last tracked
///     frame's (needs every frame's IMU data, CarriedSample::imu);
///   - the blend (the fallback, and the ablation Tracking.CarriedBridge = 0): the difference between
///     the anchored frame's pose and where the dead reckoning put it is spread over the stretch's
///     frames in a fixed share of time (velocity error plus a constant world-frame acceleration
///     error).
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/imu/inertial_residual.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/ids.h"

namespace ltlo::system {

/// The IMU data of one frame the inertial bridge needs, in the world of the frame's pose.
struct CarriedImu {
  /// Preintegration from the previous frame with a pose to this one (Frame::imu_from_last_frame).
  std::shared_ptr<const imu::Preintegrated> from_previous;
  Vec3 v_w_b = Vec3::Zero();           ///< tracking's velocity estimate, m/s
  imu::ImuBias bias;                   ///< tracking's bias estimate
  Vec3 g_w = imu::gravityWorld();      ///< gravity, m/s^2
  SE3 T_b_c;                           ///< camera in the body (IMU) frame
};

/// One output pose as the correction of carried stretches sees it.
struct CarriedSample {
  double t_s = 0.0;
  SE3 T_w_c;
  /// posed by the IMU's prediction alone (not tracked by vision)
  bool carried = false;
  /// The map whose world T_w_c is in (floating maps resolved to their parent's): the bridge's
  /// margins take tracked frames of the same world only.
  std::uint64_t world = 0;
  /// IMU data (null: not kept); the bridge needs it on every frame of a stretch, its two ends and
  /// its margins.
  std::shared_ptr<const CarriedImu> imu;
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

/// How the trajectory output corrects IMU-carried stretches.
enum class CarriedCorrection {
  kNone,    ///< as the IMU predicted them (Tracking.SmoothCarriedFrames = 0)
  kBlend,   ///< the blend only (Tracking.CarriedBridge = 0)
  kBridge,  ///< the inertial bridge, the blend where it cannot run
};

/// Options of correctCarriedStretches (from TrackingOptions, see carriedCorrectionOptions).
struct CarriedCorrectionOptions {
  /// the inertial bridge first (Tracking.CarriedBridge); the blend where it cannot run
  bool bridge = true;
  double velocity_sigma_m_s = 0.01;   ///< Tracking.CarriedVelocitySigma (blend and bridge)
  double acc_bias_sigma_m_s2 = 0.03;  ///< Tracking.AccBiasSigma (blend and bridge)
  double gyro_bias_sigma_rad_s = 0.002;  ///< Tracking.CarriedGyroBiasSigma (bridge)
  double margin_s = 0.5;                 ///< Tracking.CarriedBridgeMargin (bridge)
};

/// What correctCarriedStretches did.
struct CarriedCorrectionCounts {
  int bridged = 0;  ///< stretches solved by the inertial bridge
  int blended = 0;  ///< stretches corrected by the blend (bridge off, or it could not run)
};

/// Corrects every carried stretch smoothCarriedStretches would: by the inertial bridge
/// (system/carried_bridge.h) when options.bridge and the IMU data is there and the solve
/// succeeds, else by the blend.
CarriedCorrectionCounts correctCarriedStretches(std::vector<CarriedSample>& samples,
                                                const CarriedCorrectionOptions& options);

/// Which frames keep their IMU data for the bridge, bounded by the carried frames: every carried
/// frame, the frames of the margin_s before a stretch (the last tracked frame among them), the
/// frames tracked in another map than that last tracked frame's within kFloatingSpan_s of the
/// stretch (a floating map's frames belong to it) and the margin_s after. The tracking thread's
/// RunRecorder feeds every frame with a pose; not thread-safe.
class CarriedImuRetention {
 public:
  /// A frame held back in case a stretch follows.
  struct Pending {
    std::size_t index = 0;
    double t_s = 0.0;
    std::uint64_t map = 0;
    std::shared_ptr<const CarriedImu> imu;
  };
  /// Everything add() remembers between frames (a resumed run's recorder restores it, so its
  /// stretches keep the same IMU data as the continuous run's).
  struct State {
    std::deque<Pending> recent;
    bool stretch_open = false;
    std::uint64_t stretch_map = 0;
    double last_carried_t_s = 0.0;
    double keep_until_s = -1.0;
  };

  explicit CarriedImuRetention(double margin_s) : margin_s_(margin_s) {}
  /// Frame number `index` (the recorder's record index) at t_s, carried or not, tracked in map
  /// `map`, with its IMU data (may be null). Returns the records that keep their data now.
  std::vector<std::pair<std::size_t, std::shared_ptr<const CarriedImu>>> add(
      std::size_t index, double t_s, bool carried, std::uint64_t map, std::shared_ptr<const CarriedImu> imu);
  /// Records held back in case a stretch follows (at most margin_s of frames).
  std::size_t numPending() const { return state_.recent.size(); }
  const State& state() const { return state_; }
  void restore(State state) { state_ = std::move(state); }

  /// Longest time after a stretch's last carried frame over which frames tracked in another map
  /// keep their data (the recorder's longest floating map, RunRecorder::kFloatingMapMaxSpan_s).
  static constexpr double kFloatingSpan_s = 5.0;

 private:
  double margin_s_;
  State state_;
};

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
