#pragma once
/// Local bundle adjustment of local mapping (private to ltlo_mapping): collects the window around
/// a new keyframe from the map, runs optim::localBundleAdjust and writes the result back.
///   visual:   the keyframe and its best covisibles (window_size in all) optimised;
///   inertial: the last window_size keyframes in time optimised with their velocities and biases,
///             linked by their preintegrations, the keyframe before them fixed (ORB-SLAM3's
///             temporal window for VI-BA);
/// in both, the other keyframes observing the window's points are fixed, and so is the map's
/// origin keyframe (gauge). Observations are weighted by beta * gamma (thesis Eq. 53).
#include <atomic>
#include <memory>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"

namespace ltlo::mapping {

struct WindowBaOptions {
  int window_size = 10;          ///< keyframes optimised
  int iterations = 10;           ///< per pass (two passes: robust, then without outliers)
  std::size_t max_fixed_keyframes = 50;  ///< fixed observers kept, those sharing most points first
  double bf_px_m = 40.0;
  double min_point_beta = 0.5;   ///< points with a lower static score are left out
  int num_threads = 1;
  bool inertial = false;         ///< visual-inertial window (IMU initialised)
  Vec3 g_w = Vec3(0.0, 0.0, -9.81);
  double lambda_imu = 1.0;
  const std::atomic<bool>* stop_flag = nullptr;
};

struct WindowBaStats {
  int optimised_keyframes = 0;
  int fixed_keyframes = 0;
  int points = 0;
  int observations = 0;
  int inertial_links = 0;
  int outliers_erased = 0;
  bool aborted = false;          ///< the stop flag was raised during the optimisation
  double final_chi2 = 0.0;
};

/// Runs the window BA around `kf` on `map` (kf must belong to it). `level_sigma2` is
/// OrbExtractor::levelSigma2(). Keyframes and points that went bad meanwhile are not written.
WindowBaStats localWindowBundleAdjust(map::Map& map, const std::shared_ptr<map::KeyFrame>& kf,
                                      const WindowBaOptions& options, const std::vector<float>& level_sigma2);

}  // namespace ltlo::mapping
