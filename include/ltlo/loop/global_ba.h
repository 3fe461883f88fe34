#pragma once
/// Full bundle adjustment of a map after a loop or merge (namespace ltlo::loop), through
/// optim::localBundleAdjust with every keyframe and static point: reprojection edges weighted by
/// beta * gamma (thesis Eq. 53) and, once the IMU is initialised, inertial edges between keyframes
/// consecutive in time with every keyframe's velocity and biases and their random walk (Eq. 58) in
/// the known gravity. The loop closer runs it in its own thread; it works on a snapshot and writes
/// the results back.
#include <atomic>
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/imu/imu_types.h"
#include "ltlo/map/map.h"

namespace ltlo::loop {

struct GlobalBaOptions {
  int iterations = 10;  ///< Loop.FullBaIterations
  /// Virtual stereo baseline of the RGB-D edges (bf = fx * baseline), m.
  double virtual_baseline_m = 0.08;
  /// Points with a lower static score beta are left out (LocalMapping.MinPointBeta).
  double min_point_beta = 0.5;
  /// Gravity in the map's world (m/s^2) once the IMU is initialised: visual-inertial full BA (the
  /// origin keyframes hold their pose only). nullopt: vision only (the origins are fixed).
  std::optional<Vec3> g_w;
  double lambda_imu = 1.0;  ///< bias random-walk weight, Eq. 58 (LocalMapping.LambdaImu)
  /// Visual-inertial: the gravity direction is optimised too, from g_w (magnitude kept; the gauge
  /// keyframe holds the frame, so its two tilt angles are observable). The whole map informs it,
  /// where the IMU initialisation and its refinements saw one window (Loop.FullBaGravity).
  bool estimate_gravity = false;
  /// Visual-inertial: reprojection edges weighted by the camera noise estimated from their
  /// residuals (LocalMapping.VisualVarianceEstimation).
  bool visual_variance_estimation = true;
  int num_threads = 2;
  const std::atomic<bool>* stop_flag = nullptr;  ///< a new loop aborts the BA
};

struct GlobalBaResult {
  int keyframes = 0;
  int points = 0;
  int observations = 0;
  int inertial_links = 0;
  int outliers = 0;  ///< observations failing the chi2 test at the end (left linked)
  double initial_chi2 = 0.0;
  double final_chi2 = 0.0;
  double gravity_change_deg = 0.0;  ///< with estimate_gravity: angle between g_w and the optimised one
};

/// The optimised state of a full BA, not yet written to the map: the snapshot's keyframes and points
/// with their poses/positions at snapshot time and after the optimisation.
struct GlobalBaSolution {
  GlobalBaResult result;
  bool valid = false;  ///< false: nothing to apply (too small, aborted)
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;
  std::vector<SE3> T_w_b_before;  ///< at snapshot time
  std::vector<SE3> T_w_b_after;
  /// Visual-inertial: per keyframe, whether its velocity and biases were optimised, and their values.
  std::vector<bool> inertial;
  std::vector<Vec3> v_w_b_after;
  std::vector<imu::ImuBias> bias_after;
  std::vector<std::shared_ptr<map::MapPoint>> points;
  std::vector<Vec3> p_w_after;
  /// With estimate_gravity: the optimised gravity.
  std::optional<Vec3> g_w_after;
};

/// The optimisation part of runGlobalBundleAdjustment on a snapshot of `map` (reads the map only;
/// local mapping may run meanwhile). Invalid when aborted through options.stop_flag.
GlobalBaSolution optimizeGlobalBundleAdjustment(const map::Map& map, const GlobalBaOptions& options = GlobalBaOptions());

/// Writes `solution` into `map` and bumps its version. Keyframes of the snapshot take their optimised
/// pose (and velocity and biases when inertial); keyframes created since (not in the snapshot) move
/// with the correction T_w_b_after * T_w_b_before^-1 of their nearest spanning-tree ancestor in the
/// snapshot (ORB-SLAM's propagation; their velocity turns with it, their biases stay); points not optimised move with their reference keyframe's correction. Call with
/// local mapping paused (it writes poses and points local BA also writes). Returns the number of
/// keyframes moved by propagation.
int applyGlobalBundleAdjustment(map::Map& map, const GlobalBaSolution& solution);

/// Optimises every good keyframe's T_w_b (and v_w_b and biases with g_w) and every static point seen
/// by >= 2 of them; the map's origin keyframes are the gauge. optimizeGlobalBundleAdjustment then applyGlobalBundleAdjustment (the
/// loop closer pauses local mapping between the two). Uses the first keyframe's camera and T_b_c for all.
GlobalBaResult runGlobalBundleAdjustment(map::Map& map, const GlobalBaOptions& options = GlobalBaOptions());

}  // namespace ltlo::loop
