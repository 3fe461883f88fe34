#pragma once
/// LoopCloser (namespace ltlo::loop): the loop-closing thread. For every keyframe local mapping has
/// processed: place recognition on the static keyframes (LoopDetector), geometric verification
/// (verifyLoop), and either a loop correction in the same map (correctLoop with local mapping paused,
/// then a full BA in its own thread) or a merge with another Atlas map (mergeAtPlace). Once local
/// mapping has initialised the IMU (MappingControl::gravity_w), corrections and merges are 4-DoF
/// (yaw about gravity and translation), velocities turn with the poses, merges are welded by a
/// visual-inertial BA and the full BA is visual-inertial; before that, SE3 and vision only.
/// A map tracking started at the IMU's prediction after a loss (map::MapOrigin) also rejoins its
/// parent by a guided search around its keyframes' poses (Loop.Rejoin, guided_place_match.h).
/// The keyframe then enters the keyframe database.
///
/// Threads: local mapping calls insertKeyFrame(); the loop thread runs run(); the full BA runs in a
/// thread the closer starts and joins (a newer loop or merge aborts and joins it before changing the
/// map; it writes its result back with local mapping paused). System calls requestFinish() and joins.
/// Every correction or merge bumps the Map version(s): tracking must refresh what it holds of the
/// map (local map, reference keyframe, last pose in the old frame) when the version of its map
/// changes, and re-fetch Atlas::activeMap() (a merge may make another map active).
/// Thread-safe public API; the closer owns its queue, detector and event list.
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/timing.h"
#include "ltlo/loop/global_ba.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/place/guided_place_match.h"

namespace ltlo::map {
class ByteReader;
class ByteWriter;
}  // namespace ltlo::map

namespace ltlo::loop {

struct LoopCloserOptions {
  /// enabled, consistency, inliers, full BA iterations, static ratio; wait_for_imu only when the run
  /// has an IMU (without one gravity never comes)
  LoopOptions loop;
  /// Virtual stereo baseline of the RGB-D edges of the full BA (m).
  double virtual_baseline_m = 0.08;
  /// Points with a lower static score beta stay out of the full and welding BA
  /// (LocalMapping.MinPointBeta).
  double min_point_beta = 0.5;
  /// Weight of the bias random walk in the visual-inertial BAs, Eq. 58 (LocalMapping.LambdaImu).
  double lambda_imu = 1.0;
  /// The visual-inertial BAs estimate the camera noise from their residuals
  /// (LocalMapping.VisualVarianceEstimation).
  bool visual_variance_estimation = true;
  bool run_global_ba = true;       ///< full BA after each loop (in its own thread)
  /// The rejoin's guided search (Loop.Rejoin): windows, gate, keyframes, descriptor distance (the
  /// tracker's re-acquisition settings); its sigmas come from each map's MapOrigin.
  place::GuidedPlaceMatchOptions rejoin_search;
  std::size_t queue_capacity = 64;
};

/// Pause/resume of local mapping around a correction (System wires LocalMapper::pause/resume) and
/// the IMU state local mapping estimates.
struct MappingControl {
  std::function<void()> pause;
  std::function<void()> resume;
  /// Gravity in the run's world frame (m/s^2) once the IMU is initialised, nullopt before (or
  /// without an IMU, or not wired). Called from the loop thread; must be thread-safe.
  std::function<std::optional<Vec3>()> gravity_w = nullptr;
  /// Hands a full BA's gravity (Loop.FullBaGravity) to the IMU state local mapping publishes (the
  /// keyframes carry the BA's velocities and biases). Called from the loop thread with local mapping
  /// paused. Empty: the full BA keeps gravity fixed.
  std::function<void(const Vec3& g_w)> set_gravity_w = nullptr;
  /// Around every change of the map's world frame (correction, merge, full-BA write-back), after
  /// local mapping paused: keeps the frame being tracked out of it (System wires a ChangeGate,
  /// core/change_gate.h). Empty: no tracking to hold (tests, single-threaded runs).
  std::function<void()> hold_tracking = nullptr;
  std::function<void()> release_tracking = nullptr;
};

/// One accepted loop or merge (for logs, metrics.json and tests).
struct LoopEvent {
  bool merge = false;  ///< across maps
  bool rejoin = false;  ///< a merge found by the guided search of Loop.Rejoin (not by BoW)
  bool proximity = false;  ///< a loop found by the guided search of Loop.Proximity (not by BoW)
  double t_s = 0.0;    ///< time of the current keyframe
  map::KeyFrameId current;
  map::KeyFrameId loop;
  map::MapId map;      ///< the map kept (merge target)
  int inliers = 0;
  double correction_m = 0.0;  ///< |translation| of the current keyframe's correction
};

class LoopCloser {
 public:
  /// `timing` (may be nullptr) receives "loop.keyframe", "loop.correction", "loop.global_ba".
  LoopCloser(map::Atlas& atlas, const LoopCloserOptions& options, MappingControl mapping,
             TimingStats* timing = nullptr);
  LoopCloser(const LoopCloser&) = delete;
  LoopCloser& operator=(const LoopCloser&) = delete;
  ~LoopCloser();  ///< joins a running full BA

  /// Queues a processed keyframe (local-mapping thread). Never blocks (the loop thread may be
  /// waiting for local mapping to pause): a keyframe that finds the queue full or closed skips loop
  /// detection but still enters the keyframe database.
  void insertKeyFrame(std::shared_ptr<map::KeyFrame> kf);
  /// Detection, verification, correction/merge and database insertion of one keyframe, in the
  /// calling thread (tests, single-threaded runs; the full BA then runs synchronously too).
  void processKeyFrame(const std::shared_ptr<map::KeyFrame>& kf);

  /// Loop thread: processes queued keyframes until requestFinish(), drains the queue, waits for
  /// the full BA and returns. Exceptions are logged and end the loop.
  void run();
  void requestFinish();

  /// Keyframes waiting in the queue.
  std::size_t queuedKeyFrames() const;
  std::vector<LoopEvent> events() const;
  int numLoops() const;   ///< same-map loops corrected
  int numMerges() const;  ///< maps merged
  bool globalBaRunning() const;
  /// Blocks until no full BA is running (tests; System before writing the map).
  void waitForGlobalBa();
  /// Loop.FinalFullBa: after the run (run() returned, or single-threaded after the last keyframe;
  /// local mapping finished), a full BA of every map with at least 3 keyframes, synchronously in
  /// the caller's thread. Returns the number of maps adjusted.
  int finalGlobalBa();

  /// Loop closing's state between two keyframes, with its queue empty and no full BA running
  /// (single-threaded, or after run() returned): the candidates' consistency, the keyframes since
  /// the last correction, a pending refinement (loop_closer_state.cc). For a run resumed from an
  /// atlas file (system/run_state.h); events and counts stay this run's.
  void writeState(map::ByteWriter& out) const;
  /// Restores it before the first keyframe; throws AtlasFileError (file, section, byte).
  void readState(map::ByteReader& in);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ltlo::loop
