#pragma once
/// Bundle adjustment problems of loop closing built from a Map (private to ltlo_loop): the full BA
/// after a loop or merge and the welding BA around a merge seam. Optimised keyframes with their
/// points, the other keyframes observing those points held fixed, RGB-D / monocular reprojection
/// edges weighted by beta (point) * gamma (cluster of the observing keypoint), thesis Eq. 53, and,
/// once the IMU is initialised, inertial edges between keyframes consecutive in time (each with
/// its own velocity and biases, linked by the bias random walk, Eq. 58) in the known gravity.
#include <cstddef>
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"
#include "ltlo/optim/bundle_adjust.h"

namespace ltlo::loop {

struct MapBaOptions {
  double bf_px_m = 40.0;         ///< bf = fx * virtual baseline of the RGB-D edges (px m)
  double min_point_beta = 0.5;   ///< points with a lower static score are left out
  /// Gravity in the map's world (m/s^2): visual-inertial problem; nullopt: vision only.
  std::optional<Vec3> g_w;
  double lambda_imu = 1.0;       ///< bias random-walk weight, Eq. 58
  /// Visual-inertial: weight the reprojection edges by the camera noise estimated from their
  /// residuals (optim::inertialInformationScale; LocalMapping.VisualVarianceEstimation).
  bool visual_variance_estimation = true;
  std::size_t max_fixed_observers = 0;  ///< other keyframes seeing the points, most shared first
};

/// Which keyframes the problem optimises; `gauge` ones are held (pose only when inertial, so their
/// velocity and biases still move; fully otherwise). A keyframe in both lists is held.
struct MapBaSelection {
  std::vector<std::shared_ptr<map::KeyFrame>> optimised;
  std::vector<std::shared_ptr<map::KeyFrame>> gauge;
  /// Held completely (pose, velocity, biases), e.g. the keyframe before an inertial window.
  std::vector<std::shared_ptr<map::KeyFrame>> fixed;
};

/// The problem and what its entries are in the map (problem order).
struct MapBaProblem {
  optim::LocalBaProblem problem;
  std::vector<std::shared_ptr<map::KeyFrame>> keyframes;  ///< problem.keyframes[k] is keyframes[k]
  std::vector<std::shared_ptr<map::MapPoint>> points;     ///< problem.points[m] is points[m]
  int optimised_keyframes = 0;
  int fixed_keyframes = 0;
};

/// Builds the problem from the map's current state (reads only; thread-safe). Bad keyframes and
/// points are skipped. A point enters with at least two observations in the problem. Inertial
/// links join a keyframe and its previousKeyFrame() when both are in the problem, at least one
/// optimised, and the keyframe has its preintegration. Without any held keyframe the oldest
/// optimised one becomes the gauge.
MapBaProblem buildMapBa(const map::Map& map, const MapBaSelection& selection, const MapBaOptions& options);

/// Ids of the keyframes of `problem` that have an inertial link (their velocity and biases were
/// optimised or held).
std::vector<bool> inertialKeyFrames(const MapBaProblem& problem);

}  // namespace ltlo::loop
