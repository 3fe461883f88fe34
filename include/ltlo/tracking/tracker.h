#pragma once
/// Tracker: the single-threaded visual(-inertial) front end. Each frame is predicted (constant
/// velocity on T_w_c, or the IMU once it is initialised), matched to the last frame by projection,
/// pose-optimised, then matched to the local map (keyframes covisible with the reference keyframe)
/// and pose-optimised again. Keyframes are inserted into the map with new RGB-D map points; an
/// optional synchronous local-mapping callback runs after each one (system/ replaces it by the
/// mapping thread).
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/map.h"

namespace ltlo::tracking {

enum class TrackingState { kNotInitialised, kOk, kLost };
const char* trackingStateName(TrackingState state);

struct TrackerOptions {
  KeyFrameOptions keyframe;  ///< overlap / weak-tracking / interval decision (core settings)
  /// static keypoints with depth needed by the first frame to start a map
  int min_init_features = 100;
  /// tracking is lost below this many pose inliers after the local-map step
  int min_inliers = 30;
  /// fewest frames between keyframes (0: a keyframe may follow the previous one directly)
  int min_frames_between_keyframes = 0;
  /// new map points: all unmatched static keypoints closer than this (m), else the closest
  /// min_new_points ones (ORB-SLAM's RGB-D insertion)
  double close_depth_m = 3.0;
  int min_new_points = 100;
  /// Hamming threshold of a projection match (of 256 bits)
  int max_descriptor_distance = 100;
  /// half window of the last-frame search, level-0 px (times the keypoint's scale)
  double last_frame_radius_px = 15.0;
  /// half window of the local-map search, level-0 px (times the predicted scale)
  double local_map_radius_px = 3.0;
  /// ratio test of the local-map search (best vs second best on the same level)
  double local_map_ratio = 0.8;
  /// local keyframes at most
  int max_local_keyframes = 60;
  /// bf = fx * virtual baseline (px m) for the RGB-D edges of the pose optimisation
  double bf_px_m = 40.0;
  /// After setImuInitialised(): also optimise the pose with the inertial link to the last frame
  /// (held fixed). Off by default: the last frame's velocity is then a finite difference of
  /// vision-only poses (5-10 mm jitter per frame at 30 fps, i.e. 0.1-0.3 m/s of velocity noise), and
  /// the tight 33 ms preintegration pins the pose to it; on the noise-free simulated sequence this
  /// drifted to 0.24 m ATE. It needs velocities from VI bundle adjustment (mapping) or a prior on the
  /// previous state. Off, the IMU predicts the pose and seeds the search only.
  bool inertial_pose_optimisation = false;
};

/// Per-frame numbers for logs and tests.
struct TrackingStats {
  int last_frame_matches = 0;  ///< matches to the last frame before optimisation
  int last_frame_inliers = 0;
  int local_map_matches = 0;   ///< all matches after the local-map search
  int inliers = 0;             ///< pose inliers after the local-map step
  double overlap = 0.0;        ///< share of the reference keyframe's points tracked
  bool used_imu = false;       ///< the IMU predicted the pose
};

/// Not thread-safe (the tracking thread owns it). Reads and writes `map` through its thread-safe API.
class Tracker {
 public:
  /// `level_sigma2` is OrbExtractor::levelSigma2() (keypoint variance per pyramid level).
  Tracker(map::Map& map, const TrackerOptions& options, std::vector<float> level_sigma2);

  /// Tracks `frame` (sets its pose, map-point matches, reference keyframe) and inserts a keyframe
  /// when needNewKeyFrame(). Returns the new state.
  TrackingState track(map::Frame& frame);

  TrackingState state() const { return state_; }
  /// Camera pose of the last tracked frame (identity before initialisation).
  SE3 T_w_c() const { return last_T_w_c_; }
  const TrackingStats& stats() const { return stats_; }

  /// Keyframe decision for the last tracked frame (KeyFrameOptions): overlap below max_overlap,
  /// or weak tracking, or max_interval_s since the last keyframe; and at least
  /// min_frames_between_keyframes frames since it.
  bool needNewKeyFrame() const;
  /// Promotes the last tracked frame to a keyframe with its matches and new close map points,
  /// updates the covisibility graph and runs the local-mapping callback.
  std::shared_ptr<map::KeyFrame> createKeyFrame();

  /// Synchronous local mapping after each new keyframe (e.g. a test running localBundleAdjust).
  using LocalMappingCallback = std::function<void(map::Map&, const std::shared_ptr<map::KeyFrame>&)>;
  void setLocalMappingCallback(LocalMappingCallback callback) { local_mapping_ = std::move(callback); }

  /// IMU hook (system/ calls it after IMU initialisation): from now on frames carrying
  /// imu_from_last_frame are predicted by preintegration and pose-optimised with the inertial link.
  /// The world must be gravity-aligned (g_w) by then.
  void setImuInitialised(const imu::ImuBias& bias, const Vec3& g_w);
  bool imuInitialised() const { return imu_initialised_; }
  const imu::ImuBias& bias() const { return bias_; }

  int numKeyFrames() const { return num_keyframes_; }
  map::KeyFrameId referenceKeyFrame() const { return reference_kf_; }

 private:
  TrackingState initialise(map::Frame& frame);
  SE3 predictPose_T_w_b(map::Frame& frame);
  int matchLastFrame(map::Frame& frame, double radius_scale);
  int searchLocalMap(map::Frame& frame);
  /// Pose-only optimisation over frame.map_points; marks outliers; returns inliers.
  int optimisePose(map::Frame& frame, const SE3& T_w_b_init, bool drop_outliers);
  void updateLocalMap(const map::Frame& frame);
  int addNewMapPoints(map::KeyFrame& kf, map::Frame& frame);

  map::Map& map_;
  TrackerOptions options_;
  std::vector<float> level_sigma2_;
  LocalMappingCallback local_mapping_;

  TrackingState state_ = TrackingState::kNotInitialised;
  TrackingStats stats_;
  std::optional<map::Frame> last_frame_;  ///< last successfully tracked frame
  SE3 last_T_w_c_;
  std::optional<SE3> velocity_T_last_cur_;  ///< constant-velocity model: T_c_last^-1 motion
  int frames_since_keyframe_ = 0;
  double last_keyframe_t_s_ = 0.0;
  map::KeyFrameId reference_kf_;
  map::KeyFrameId last_kf_;
  int num_keyframes_ = 0;
  std::vector<map::KeyFrameId> local_keyframes_;
  std::vector<map::MapPointId> local_points_;

  bool imu_initialised_ = false;
  imu::ImuBias bias_;
  Vec3 g_w_ = Vec3(0.0, 0.0, -9.81);
  std::optional<imu::Preintegrated> imu_since_keyframe_;
};

}  // namespace ltlo::tracking
