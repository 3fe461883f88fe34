#pragma once
/// Tracked poses against the IMU before gravity is known (issue 32, the occluded start).
///
/// Three body poses a, b, c (R_w_b, p_w_b in the map's world) with the preintegrated deltas of the
/// two intervals between them (dR, dV, dP over dt0 from a to b, over dt1 from b to c) leave gravity
/// as the only unknown once the velocities are eliminated (the preintegration identities of Forster
/// et al., solved for v_a and v_b and subtracted):
///
///   (p_c - p_b) / dt1 - (p_b - p_a) / dt0 - R_b dP1 / dt1 + R_a dP0 / dt0 - R_a dV0 = g_w (dt0 + dt1) / 2.
///
/// So every window of three poses gives an estimate of g_w. Poses that follow the camera give the
/// same g_w each time (up to the tracking noise: 1 mm over 0.1 s intervals is about 0.25 m/s^2).
/// When tracking changes the world it follows, from a mover that held the view to the room behind it,
/// the velocity of the poses changes without any force the accelerometer felt, and the window across
/// the change gives a g_w off by that change over the window's mean interval (0.3 m/s over 0.1 s:
/// 3 m/s^2). The first window has no earlier estimate and is compared by its norm with 9.81 m/s^2.
///
/// The bound grows with the poses' own uncertainty: a window is inconsistent only when its
/// difference also exceeds 5 sigma of the estimate, sigma from the three poses' position sigmas
/// (at 15 Hz and 320x240 with 40-70 inliers, tracking jitters by 1-2 cm, several m/s^2).
///
/// What it cannot see: poses that follow a mover moving at a constant velocity relative to the
/// camera differ from the truth by a constant velocity, which cancels above; only the change is seen.
#include <vector>
#include <utility>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"

namespace ltlo::imu {

struct PoseGravityCheckOptions {
  double window_s = 0.1;  ///< least time between the poses of a window (whole frame intervals; 1 ms tolerance)
  /// Largest difference of a window's g_w from the mean of the earlier ones (or of its norm from
  /// 9.81 m/s^2 for the first window) still called consistent, m/s^2
  double max_error_m_s2 = 3.0;
  /// The bound is at least this many standard deviations of the window's estimate
  double noise_sigmas = 5.0;
};

struct PoseGravityVerdict {
  bool checked = false;       ///< a window closed with this pose
  bool consistent = true;
  double error_m_s2 = 0.0;    ///< the window's difference (see PoseGravityCheckOptions)
  double bound_m_s2 = 0.0;    ///< the largest difference called consistent for this window
  Vec3 g_w = Vec3::Zero();    ///< the window's estimate
};

class PoseGravityCheck {
 public:
  /// The saved state (run-state files): nodes, the open interval and the reference.
  struct Node {
    double t_s = 0.0;
    Mat3 R_w_b = Mat3::Identity();
    Vec3 p_w_b = Vec3::Zero();
    double sigma_m = 0.0;  ///< the position's standard deviation
  };
  struct Interval {
    Mat3 dR = Mat3::Identity();
    Vec3 dV = Vec3::Zero();
    Vec3 dP = Vec3::Zero();
    double dt_s = 0.0;
  };
  struct State {
    std::vector<Node> nodes;           ///< at most the last three
    std::vector<Interval> intervals;   ///< between consecutive nodes (nodes.size() - 1 of them)
    Interval open;                     ///< from the last node to the last pose added
    Vec3 g_sum = Vec3::Zero();         ///< sum of the consistent windows' g_w
    int windows = 0;                   ///< consistent windows in g_sum
    double max_error_m_s2 = 0.0;       ///< largest error seen since the last reset()
  };

  explicit PoseGravityCheck(const PoseGravityCheckOptions& options) : options_(options) {}

  /// Adds the pose of a tracked frame (its position's standard deviation, m, finite) and the IMU
  /// interval from the previous pose added (its bias-corrected deltas; ignored for the first pose
  /// after a reset). A verdict is given when the pose closes a window (its interval from the last
  /// node reached window_s) and two nodes precede it.
  PoseGravityVerdict add(double t_s, const SE3& T_w_b, double sigma_m, const Mat3& dR, const Vec3& dV, const Vec3& dP,
                         double dt_s);

  /// Forgets every pose: the next one starts a new chain (a lost frame, a recovery).
  void reset();
  bool empty() const { return state_.nodes.empty(); }

  const State& state() const { return state_; }
  void restore(State state) { state_ = std::move(state); }

 private:
  PoseGravityCheckOptions options_;
  State state_;
};

}  // namespace ltlo::imu
