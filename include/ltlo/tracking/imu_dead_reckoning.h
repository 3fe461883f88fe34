#pragma once
/// The pose of the frames before a run's first map (issue 32, Tracking.PreMapImuPose): while the view
/// is too poor to start a map (a box over the whole view, darkness, a blank wall), the IMU alone keeps
/// a pose, so that every frame has one and the map starts where the robot is rather than at the
/// origin.
///
/// The world is the first frame's body frame (the map's own convention: a first keyframe made at
/// frame 0 sits at identity), so a map that starts at frame 0 is unchanged. Per frame, from the
/// preintegration of the IMU since the previous frame (imu/preintegration.h):
/// - at rest (the zero-velocity test says so, imu/zero_velocity_detector.h): the pose is held and the
///   velocity is zero; the gyro bias is the mean gyro reading over the rest so far (all its frames'
///   IMU steps: a low-cost gyro's 0.3 s window mean is off by a few mrad/s), and gravity in the world
///   is g_w = -R_w_b f_mean, the accelerometer's mean specific force (f = R_w_b^T (a - g) at a = 0).
///   The accelerometer bias is absorbed into that gravity and cancels as long as the orientation
///   stays near the rest's (a ground robot's pitch and roll barely change);
/// - moving, with gravity known (a rest seen before): the preintegrated deltas at that gyro bias,
///     R_j = R_i dR,  v_j = v_i + g_w dt + R_i dv,  p_j = p_i + v_i dt + g_w dt^2 / 2 + R_i dp;
/// - moving without a rest seen: the orientation from the gyroscope alone, the position held (the
///   velocity is unknown and gravity unseparated from the acceleration), said once in the log.
/// The zero-velocity test sees a smooth start of motion only once it has built up (on the simulated
/// robot's speed-up ramp about 0.2 s late, at 0.1 m/s): the frames it still called rest were
/// moving, and their readings are not the rest's. So the first moving frame after a rest goes back
/// to the last rest frame at least `replay_s` older than itself, takes that frame's state, gravity and
/// gyro bias, and integrates every frame since then again.
/// A frame without IMU data holds the pose. Not thread-safe (the tracking thread owns it).
#include <deque>
#include <optional>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/preintegration.h"

namespace ltlo::tracking {

class ImuDeadReckoning {
 public:
  /// The first frame, at t0_s: identity pose, zero velocity, nothing known of gravity or the gyro
  /// bias. `replay_s`: how far back before the first moving frame a rest is trusted (s; twice the
  /// zero-velocity test's window is safe).
  ImuDeadReckoning(double t0_s, double replay_s);

  /// The next frame, at t_s: `imu` is the preintegration since the previous frame (null: none, the
  /// pose is held); `at_rest` whether the zero-velocity test says rest at this frame.
  void propagate(double t_s, const imu::Preintegrated* imu, bool at_rest);

  const SE3& T_w_b() const { return state_.T_w_b; }
  const Vec3& v_w_b() const { return state_.v_w_b; }
  /// Gravity in the world (m/s^2), once a rest was seen.
  const std::optional<Vec3>& g_w() const { return state_.g_w; }
  const Vec3& gyroBias() const { return state_.b_g; }
  /// Whether the position is integrated (a rest was seen) or held (orientation only).
  bool positionIntegrated() const { return state_.g_w.has_value(); }
  /// Gravity and the gyro bias of the rest the current state integrates from (its readings up to the
  /// trusted rest frame), once a rest was seen.
  std::optional<imu::RestEstimate> restEstimate() const;

 private:
  struct State {
    SE3 T_w_b;
    Vec3 v_w_b = Vec3::Zero();
    std::optional<Vec3> g_w;
    Vec3 b_g = Vec3::Zero();
    // The current rest's raw readings integrated over its frames (reset when a rest begins).
    Vec3 rest_gyro_sum = Vec3::Zero();  ///< rad
    Vec3 rest_acc_sum = Vec3::Zero();   ///< m/s
    double rest_s = 0.0;
  };
  /// One frame of the last replay_s and a bit: its IMU, whether it was called rest, the state after it.
  struct Step {
    double t_s = 0.0;
    std::optional<imu::Preintegrated> imu;
    bool rest = false;
    State after;
  };
  static void restUpdate(const imu::Preintegrated* imu, bool rest_begins, State* state);
  static void integrate(const imu::Preintegrated* imu, State* state);
  /// The first moving frame after a rest: from the last rest step at least replay_s old (else the
  /// oldest rest step held) the steps after it integrated again as moving.
  void replayFromTrustedRest(double t_s);

  double replay_s_;
  State state_;
  std::deque<Step> history_;
};

}  // namespace ltlo::tracking
