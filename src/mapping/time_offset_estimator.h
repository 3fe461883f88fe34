#pragma once
// Online camera-IMU time offset (IMU.TimeOffset's remainder): the shift s of the IMU interval
// against the camera's stamps, [t_i + s, t_j + s] on the IMU clock for the images at t_i and t_j.
//
// Estimated in the mapping thread after each local BA, from the chain of keyframes the BA just
// refined: the rotation between two consecutive keyframes seen by vision, R_w_bi^T R_w_bj, against
// the gyroscope's delta_R over the interval each link was cut with (shifts s_b, s_e at its ends),
// moved to a common shift s to first order in the end rates,
//   delta_R(s, b_g) = Exp(-w_b (s - s_b)) delta_R(b_g) Exp(w_e (s - s_e)),   w = gyro reading - b_g,
//   r = Log(delta_R(s, b_g)^T R_w_bi^T R_w_bj),
// weighted by each link's rotation information, Huber-robust, with a prior on s (the calibration,
// LocalMapping.TimeOffsetPriorSigma) and a weak one on b_g (the mapper's estimate): Gauss-Newton in
// the four unknowns (s, b_g). This is the rotation block of the inertial residual with the
// preintegration interval shifted: vision fixes the keyframe rotations far better than the gyro, so
// the mismatch is the clock's. s is observed through changes of the angular rate between a link's
// ends (a constant turn looks the same at any shift): the marginal sigma says how well, and the
// estimate is used only when it is informative.
//
// Then the links of the map's chain are moved to the new shift exactly (imu::Preintegrated::
// moveBoundary hands IMU steps between consecutive links), and tracking cuts new frames with it.
#include <optional>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/map.h"

namespace ltlo::mapping {

/// One inertial link between consecutive keyframes, with the rotations the BA gave them.
struct TimeOffsetLink {
  Mat3 R_w_b_begin;
  Mat3 R_w_b_end;
  imu::Preintegrated pim;  ///< from the earlier keyframe to the later (its shifts say how it was cut)
};

struct TimeOffsetEstimate {
  double shift_s = 0.0;       ///< estimated shift (s)
  double sigma_s = 0.0;       ///< its marginal standard deviation (s)
  Vec3 gyro_bias = Vec3::Zero();
  int links = 0;              ///< links used
  double rms_rad = 0.0;       ///< RMS rotation residual at the estimate (rad)
};

struct TimeOffsetOptions {
  double prior_shift_s = 0.0;    ///< centre of the prior (the calibration's remainder: 0)
  double prior_sigma_s = 0.03;   ///< LocalMapping.TimeOffsetPriorSigma
  double gyro_bias_sigma_rad_s = 0.01;  ///< weak prior on b_g around the given one
  double max_abs_shift_s = 0.05;  ///< supported range (the reader's IMU margin)
  double huber_whitened = 3.0;    ///< Huber threshold on a link's whitened residual norm
  int iterations = 10;
};

/// Gauss-Newton over (shift, b_g) from `links`; nullopt with fewer than 3 links or a non-finite
/// solve. The shift is clamped to +-max_abs_shift_s.
std::optional<TimeOffsetEstimate> estimateTimeOffset(const std::vector<TimeOffsetLink>& links, double initial_shift_s,
                                                     const Vec3& gyro_bias, const TimeOffsetOptions& options);

/// The links of `newest`'s IMU chain in `map`, newest first, at most `max_links` (stops at a
/// keyframe without a link or whose predecessor is gone).
std::vector<TimeOffsetLink> chainLinks(const map::Map& map, const map::KeyFrame& newest, int max_links);

/// Moves the IMU boundary at every keyframe K of `map` whose link and whose successor's link both
/// exist (and the successor's id is at most `newest_processed`: a keyframe tracking is creating
/// now is not touched) to `shift_s`, where it is more than `min_move_s` away and the move is shorter
/// than half of either link. Mapping thread (the links' writer); returns the boundaries moved.
int moveChainBoundaries(const map::Map& map, map::KeyFrameId newest_processed, double shift_s, double min_move_s);

}  // namespace ltlo::mapping
