#pragma once
/// The inertial bridge of an IMU-carried stretch (trajectory output, system/carried_stretch.h).
///
/// Tracking dead-reckons a carried stretch from the last tracked frame S with S's biases; an
/// accelerometer bias error is constant in the BODY frame, so when the robot turns its world-frame
/// effect turns with it, and a correction that only knows the end discrepancy in the world frame
/// (the blend) cannot follow it. Once the frame after the stretch, A, is anchored by vision, the
/// bridge solves the stretch again as a small batch problem in the final trajectory's world:
///   - per frame a body pose and velocity, consecutive frames linked by the frames' own IMU
///     preintegration (optim::EdgeInertial, gravity from the map);
///   - one gyroscope and one accelerometer bias for the whole window, with a prior about S's
///     estimate (Tracking.CarriedGyroBiasSigma, Tracking.AccBiasSigma, plus the random walk over
///     the window);
///   - S's pose held, its velocity with a prior about tracking's estimate
///     (Tracking.CarriedVelocitySigma); A's pose held;
///   - margins: the tracked frames of the margin_s before S and after A (same world), with a prior
///     on their final poses: they tell the velocities at both ends and the biases.
/// The carried frames' output poses are the solved ones; nothing else changes.
#include <cstddef>
#include <optional>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/system/carried_stretch.h"

namespace ltlo::system {

struct CarriedBridgeOptions {
  double velocity_sigma_m_s = 0.01;      ///< S's velocity about tracking's estimate, m/s
  double acc_bias_sigma_m_s2 = 0.03;     ///< b_a about S's estimate, m/s^2 (random walk added)
  double gyro_bias_sigma_rad_s = 0.002;  ///< b_g about S's estimate, rad/s (random walk added)
  double margin_s = 0.5;                 ///< tracked frames before S and after A, s (0: none)
  double margin_position_sigma_m = 0.003;     ///< prior on a margin frame's final position, m
  double margin_rotation_sigma_rad = 0.0035;  ///< prior on its final rotation, rad
  int max_iterations = 30;
};

/// Most a frame's preintegration interval may differ from the time between the two frames' stamps
/// (the camera-IMU offset estimate moving between them), s; beyond, the frames are not linked.
constexpr double kMaxBridgeLinkMismatch_s = 0.005;

struct CarriedBridgeResult {
  std::vector<SE3> T_w_c;  ///< camera poses of samples [begin, end)
  imu::ImuBias bias;       ///< the window's biases
  int margin_before = 0;   ///< tracked frames before S in the window
  int margin_after = 0;    ///< tracked frames after A
  double initial_chi2 = 0.0;
  double final_chi2 = 0.0;
  int iterations = 0;
};

/// Solves the carried frames samples[begin, end) between S = samples[begin - 1] and
/// A = samples[end] (file comment). Needs S and A in one world, the IMU data (CarriedSample::imu)
/// on S and on every frame after it up to A, each linked to the one before it (its preintegration
/// spans the time between their stamps within kMaxBridgeLinkMismatch_s). Returns nullopt when that
/// is missing or the solve does not give a finite result (the caller then blends).
std::optional<CarriedBridgeResult> bridgeCarriedStretch(const std::vector<CarriedSample>& samples,
                                                        std::size_t begin, std::size_t end,
                                                        const CarriedBridgeOptions& options);

}  // namespace ltlo::system
