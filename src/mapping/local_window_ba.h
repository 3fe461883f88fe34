#pragma once
/// Local bundle adjustment of local mapping (private to ltlo_mapping): collects the window around
/// a new keyframe from the map, optimises it and writes the result back.
///   visual:   the keyframe and its best covisibles (window_size in all) optimised;
///   inertial: the last window_size keyframes in time optimised with their velocities and biases,
///             linked by their preintegrations, the keyframe before them fixed (ORB-SLAM3's
///             temporal window for VI-BA);
/// in both, the other keyframes observing the window's points are fixed, and so is the map's
/// origin keyframe (gauge). Observations are weighted by w = beta * gamma (thesis Eq. 53).
///
/// Robust VIBA (thesis Eq. 50-58, WindowBaOptions::robust): `alternations` rounds of
///   1. states and points for fixed Gamma, B (optim::LocalBaGraph: IMU, bias walk and
///      w^2 rho_H(|r|^2) per observation, Eq. 50, 53, 58);
///   2. Gamma, B for fixed states and points in closed form (static_score_update.h, Eq. 51-57),
///      from the whitened residuals of the optimised keyframes' observations and the depth
///      disagreement of the window's points with the optimised keyframes' depth images (Eq. 56);
/// then beta goes back to the points, Gamma to the optimised keyframes, points whose beta ended
/// below min_point_beta are deleted, and observations of the remaining points failing the chi2
/// gate are erased. No observation is erased before beta is estimated.
/// Plain VIBA (robust = false): weights from the points' beta and the keyframes' Gamma as they
/// are, ORB-SLAM's two passes (robust, then without the observations failing the gate).
#include <atomic>
#include <memory>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"
#include "static_score_update.h"

namespace ltlo::mapping {

struct WindowBaOptions {
  int window_size = 10;          ///< keyframes optimised
  int iterations = 10;           ///< solver iterations per state step (plain: per pass)
  std::size_t max_fixed_keyframes = 50;  ///< fixed observers kept, those sharing most points first
  /// observations of one point from fixed keyframes kept, those of the fixed keyframes sharing most
  /// points first (0: all)
  std::size_t max_fixed_observations_per_point = 0;
  /// Observations from fixed keyframes at most this many times those of the optimised keyframes (0:
  /// no limit): when the window's points have more, the per-point limit above is lowered to the
  /// largest that keeps them within it (at least 1). Bounds local BA on revisited places; a window
  /// within it is built as without it.
  double max_fixed_observation_ratio = 0.0;
  /// Robust: Eq. 56's probe points at most this many times the window's points (0: no limit), an
  /// even stride through them in the fixed keyframes' order when more. A window within it is built
  /// as without it.
  double max_probe_point_ratio = 0.0;
  double bf_px_m = 40.0;
  double min_point_beta = 0.5;   ///< points with a lower static score are left out (robust: deleted)
  int num_threads = 1;
  bool inertial = false;         ///< visual-inertial window (IMU initialised)
  Vec3 g_w = Vec3(0.0, 0.0, -9.81);
  double lambda_imu = 1.0;
  /// optim::LocalBaProblem::held_acc_bias_sigma_m_s2: how well the held keyframes' accelerometer
  /// bias is known (m/s^2; 0: exactly).
  double held_acc_bias_sigma_m_s2 = 0.0;
  /// Inertial, in a map started at the IMU's prediction after a loss (map::Map::origin()): its gauge
  /// keyframe is held in pose and biases only, its velocity is optimised
  /// (LocalMapping.GaugeVelocityFree). That first keyframe sits at the IMU's dead-reckoned state,
  /// whose velocity is off by the drift of the loss; held, the inertial links pass that error on to
  /// every keyframe of the window and tracking follows it.
  bool gauge_velocity_free = false;
  /// With gauge_velocity_free: a prior on that velocity about the dead-reckoned one with the
  /// prediction's standard deviation (map::MapOrigin, LocalMapping.GaugeVelocityPrior).
  bool gauge_velocity_prior = false;
  double huber_chi2 = 7.815;     ///< rho_H threshold on the whitened |r|^2 (3-D edges; 2-D: 5.991)
  /// The robust VIBA above (Mapping.RobustBeta); false: the plain VIBA.
  bool robust = true;
  int alternations = 3;          ///< robust: state <-> score rounds
  /// Robust: a cluster changes its score only on the window's evidence (Eq. 56 depth samples, or
  /// residuals of points seen twice or more), and a point seen once in a cluster without any keeps
  /// its beta (LocalMapping.ScoresNeedEvidence).
  bool evidence_only = true;
  StaticScoreOptions scores;     ///< robust: the closed forms' weights
  const std::atomic<bool>* stop_flag = nullptr;
};

struct WindowBaStats {
  int optimised_keyframes = 0;
  int fixed_keyframes = 0;
  int points = 0;
  int observations = 0;
  int fixed_observations = 0;       ///< of observations, those by fixed keyframes
  int fixed_observation_limit = 0;  ///< the per-point limit on fixed observations applied (0: none)
  int inertial_links = 0;
  int outliers_erased = 0;
  int dynamic_points_erased = 0;  ///< robust: beta ended below min_point_beta
  int score_steps = 0;            ///< robust: Gamma/B steps completed
  int probe_points = 0;           ///< robust: points of the fixed keyframes only, projected for Eq. 56
  int solver_iterations = 0;      ///< of the optimiser, over all rounds
  double c_hat = 0.0;             ///< robust: the last c^ of Eq. 53
  bool aborted = false;          ///< the stop flag was raised during the optimisation
  double final_chi2 = 0.0;
  /// Robust: optimised keyframes whose set of static keypoints changed with their new Gamma (their
  /// BoW must follow).
  std::vector<std::shared_ptr<map::KeyFrame>> static_set_changed;
};

/// Runs the window BA around `kf` on `map` (kf must belong to it). `level_sigma2` is
/// OrbExtractor::levelSigma2(). Keyframes and points that went bad meanwhile are not written.
WindowBaStats localWindowBundleAdjust(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf,
                                      const WindowBaOptions& options, const std::vector<float>& level_sigma2);

}  // namespace ltlo::mapping
