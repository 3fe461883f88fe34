#pragma once
/// IMU initialisation of local mapping (private to ltlo_mapping): inertial-only optimisation of
/// velocities, one bias pair and the gravity direction over the keyframes' IMU chain with their
/// (fixed) poses, then refinements by a full visual-inertial BA (poses, velocities, per-keyframe
/// biases, gravity direction and points); scale is known from depth, and the map is not rotated (g_w
/// in the map frame). The zero-mean bias priors follow the IMU's noise and random walk
/// (optim::biasPriorInformation, ImuInit.BiasPriorSamples).
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/core/settings.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"

namespace ltlo::mapping {

/// Keyframes in time order linked by preintegrations: pims[k] goes from keyframes[k] to k + 1.
struct ImuChain {
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
  std::vector<std::shared_ptr<const imu::Preintegrated>> pims;
  double span_s() const { return keyframes.empty() ? 0.0 : keyframes.back()->t_s() - keyframes.front()->t_s(); }
};

/// The chain ending at `newest`, followed back through previousKeyFrame() while each link has a
/// preintegration and the keyframe is live.
ImuChain imuChainEndingAt(const map::Map& map, const std::shared_ptr<map::KeyFrame>& newest);

/// `chain` cut after its newest keyframe whose static share of the view with depth
/// (KeyFrame::staticAreaRatio) is at least `min_static_ratio` (ImuInit.MinStaticRatio): while an
/// occluder fills the view, vision fixes the keyframe poses too loosely for gravity and the biases.
/// Empty when no keyframe qualifies.
ImuChain endAtStaticView(ImuChain chain, double min_static_ratio);

/// `chain` from its first keyframe later than `floor_t_s` on (unchanged for a negative floor).
ImuChain startAfter(ImuChain chain, double floor_t_s);

struct ImuInitEstimate {
  Vec3 g_w = Vec3::Zero();
  imu::ImuBias bias;
  int keyframes = 0;
  double span_s = 0.0;
  double final_chi2 = 0.0;
  /// Posterior covariance of the world acceleration a prediction integrates ((m/s^2)^2; see
  /// optim::inertialAccelerationCovariance), over the estimate's window.
  Mat3 acceleration_covariance_w = Mat3::Zero();
};

/// Median over the chain's links of the inertial residual's whitened chi2 per degree of freedom
/// (r^T Sigma^-1 r / 9, the preintegration's own covariance) at the keyframes' current states, the
/// earlier keyframe's bias and gravity `g_w`: about 1 when the IMU behaves as IMU.Noise* say and the
/// calibration (IMU.T_b_c1, the clock) is right; 0 without links.
double medianInertialChi2PerDof(const ImuChain& chain, const Vec3& g_w);

/// Runs optim::initializeImu on `chain` from `bias_init` (priors and iterations from `options`) and,
/// on a finite result, sets every chain keyframe's velocity and bias. nullopt on a non-finite result.
/// With `rest` (the rest before the first map, ImuInit.FromPreMapRest): gravity is held at the
/// rest's, and the gyro bias starts at the rest's mean reading with a prior there of the mean's own
/// variance, IMU.NoiseGyro^2 / rest_s, plus the bias random walk over the chain and the rest.
std::optional<ImuInitEstimate> initialiseImuOnChain(const ImuChain& chain, const ImuInitOptions& options,
                                                    const imu::ImuBias& bias_init,
                                                    const imu::RestEstimate* rest = nullptr);

/// IMU initialisation from rest (ImuInit.FromRest, issue 32). The chain's newest keyframe is one
/// tracking made at rest (KeyFrame::atRest): its IMU link from the keyframe before is a standstill.
/// At rest the link's rotation is the gyro bias alone and its velocity delta the specific force of
/// gravity, so b_g = b_g0 + Log(delta_R) / dt (the link reintegrated at it once more), g_w = -R_w_b
/// delta_v / dt scaled to 9.81 m/s^2, b_a kept (rest cannot tell it from a tilt of gravity; the later
/// refinements in motion estimate it). The two keyframes of the link get v = 0, every keyframe of
/// the chain the biases (the refinement BA holds the oldest ones with theirs). The acceleration
/// covariance is that of the unknown b_a (`acc_bias_sigma_m_s2`, Tracking.AccBiasSigma) plus the
/// mean reading's noise. nullopt when the link is missing, too short (< `min_rest_s`) or rotates
/// more than rest allows (0.01 rad/s beyond the bias).
std::optional<ImuInitEstimate> initialiseImuAtRest(const ImuChain& chain, double min_rest_s,
                                                   double acc_bias_sigma_m_s2);

/// What the refinement BA needs besides ImuInitOptions.
struct RefinementContext {
  double bf_px_m = 40.0;         ///< RGB-D edges (as local BA)
  double min_point_beta = 0.5;   ///< points with a lower static score are left out
  double lambda_imu = 1.0;       ///< bias random-walk weight, Eq. 58
  bool visual_variance_estimation = true;  ///< LocalMapping.VisualVarianceEstimation
  int num_threads = 1;
  std::vector<float> level_sigma2;  ///< OrbExtractor::levelSigma2()
  /// A refinement is written back only when its acceleration sigma (chainAccelerationCovariance at
  /// the refined states) is at most this (m/s^2): the current estimate's, so a refinement over a
  /// shorter or worse window (a new map's first seconds) never replaces a better-informed estimate.
  double max_acceleration_sigma_m_s2 = std::numeric_limits<double>::infinity();
  /// ... and only when its accelerometer bias is at most this (m/s^2): a first initialisation's
  /// ImuInit.MaxAccBias (estimateImu sets it).
  double max_acc_bias_m_s2 = std::numeric_limits<double>::infinity();
};

struct ImuRefinementStats {
  int optimised_keyframes = 0;
  int fixed_keyframes = 0;
  int points = 0;
  int observations = 0;
  double visual_sigma_scale = 1.0;  ///< estimated camera noise over the modelled one (sqrt of the variance factor)
  double initial_chi2 = 0.0;
  double final_chi2 = 0.0;
  /// not written: its accelerometer bias was beyond RefinementContext::max_acc_bias_m_s2
  bool implausible_bias = false;
};

/// The refinement of the IMU initialisation (ORB-SLAM3's VI-BA 1 and 2, without scale): a full
/// visual-inertial BA of the latest ImuInit.RefineMaxKeyFrames keyframes of `chain` with their
/// static points, per-keyframe velocities and biases (bias random walk between consecutive ones,
/// the weak zero-mean prior on the oldest) and the gravity direction starting from `g_w`; the
/// keyframe before the window and the other keyframes seeing the points are held, else the oldest
/// optimised keyframe's pose is the gauge. On a finite result writes poses, velocities, biases and
/// points back (bumping the map version, so tracking re-anchors) and returns the new g_w and the
/// newest keyframe's biases; nullopt (nothing written) otherwise.
std::optional<ImuInitEstimate> refineImuWithVisualInertialBa(map::Map& map, const ImuChain& chain, const Vec3& g_w,
                                                             const ImuInitOptions& options,
                                                             const RefinementContext& context,
                                                             ImuRefinementStats* stats = nullptr);

/// Velocity (and, when it is still zero, bias) of a keyframe inserted after the initialisation,
/// predicted from its predecessor through the preintegration when tracking left it at zero.
void predictInertialState(const map::Map& map, map::KeyFrame& kf, const Vec3& g_w);

}  // namespace ltlo::mapping

namespace ltlo::mapping {

/// Local mapping's IMU step on `chain`. `current` absent (first initialisation): the inertial-only
/// initialisation, then, with ImuInit.VisualInertialRefinement, at once the visual-inertial BA from
/// its result (the inertial-only problem takes the tracked poses as exact, so their errors go into
/// the biases and gravity; ORB-SLAM3's initialisation runs its full inertial BA the same way).
/// `current` given (a refinement): the visual-inertial BA from current->g_w, or without
/// ImuInit.VisualInertialRefinement the inertial-only initialisation again from current->bias.
/// nullopt when no finite estimate came out, or when a first initialisation's accelerometer bias
/// exceeds ImuInit.MaxAccBias (then *implausible_bias is set, if given): the refined estimate's, or
/// the inertial-only one's when no refinement is applied (the visual-inertial BA often corrects an
/// inertial-only estimate that took the tracked poses as exact). In both cases nothing of the map
/// changed.
std::optional<ImuInitEstimate> estimateImu(map::Map& map, const ImuChain& chain, const ImuInitOptions& options,
                                           const RefinementContext& context,
                                           const std::optional<ImuInitEstimate>& current,
                                           bool* implausible_bias = nullptr);

}  // namespace ltlo::mapping
