#pragma once
/// LocalMapper (namespace ltlo::mapping): the local-mapping thread. For every keyframe tracking
/// inserted into the map (with its matched and new close RGB-D points already linked): recent
/// map-point culling, duplicate fusion with the covisible neighbours, the robust visual-inertial
/// bundle adjustment of thesis Eq. 50-58 over a sliding window (static scores Gamma of the
/// keyframes' clusters and beta of the points re-estimated with the states; points that end
/// dynamic deleted; a keyframe whose static features changed gets a new BoW and keyframe-database
/// entry), keyframe culling, and the IMU
/// initialisation (inertial-only optimisation of gravity direction, velocities and biases; scale is
/// known from depth) followed by VI-BA refinements. Processed keyframes go on to loop closing.
///
/// Threads: tracking calls insertKeyFrame(); the mapping thread runs run(); loop closing calls
/// pause()/resume(); System calls requestFinish() and joins. Thread-safe public API; the mapper owns
/// its queue and counters, the Atlas owns the maps (lock order in map/atlas.h; the mapper holds no
/// lock of its own while calling into the map).
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "ltlo/core/blocking_queue.h"
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/timing.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/mapping/mapping_timeline.h"

namespace bow {
class Vocabulary;
}

namespace ltlo::map {
class ByteReader;
class ByteWriter;
}  // namespace ltlo::map

namespace ltlo::mapping {

struct LocalMapperOptions {
  LocalMappingOptions local_mapping;  ///< window size, BA iterations, redundancy for culling
  /// lambda_s, lambda_p, lambda_phi of the robust VIBA's priors (Eq. 55-57)
  SegmentationOptions segmentation;
  ImuInitOptions imu_init;            ///< when and how the IMU is initialised
  /// Recomputes the BoW of keyframes whose static features change with a refined Gamma (and
  /// their keyframe-database entry); nullptr: their BoW stays as tracking computed it.
  std::shared_ptr<const bow::Vocabulary> vocabulary;
  bool use_imu = true;                ///< false: visual-only BA, no IMU initialisation
  /// bf = fx * virtual baseline (px m) of the RGB-D reprojection edges (as tracking's).
  double bf_px_m = 40.0;
  int ba_threads = 1;                 ///< linearisation threads of the local BA
  std::size_t queue_capacity = 64;    ///< keyframes waiting; insertKeyFrame blocks beyond
  /// Refinements of the IMU estimate (a full visual-inertial BA with the gravity direction, or with
  /// ImuInit.VisualInertialRefinement = 0 the inertial-only initialisation again on the refined
  /// poses), at these keyframe-time delays after the first initialisation (s, increasing; ORB-SLAM3
  /// runs its VI-BA 1 and 2 at about 5 and 15 s).
  std::vector<double> imu_refinement_delays_s = {5.0, 15.0};
  /// Besides those, the estimate is refined again every ImuInit.RefineInterval of keyframe time,
  /// until the first of them always, then while its acceleration sigma
  /// (ImuState::acceleration_covariance_w) is above this (m/s^2;
  /// System sets Tracking.AccBiasSigma, the uncertainty tracking assumes at least): an
  /// initialisation from the first MinTime seconds is refined as its window grows, until it is as
  /// good as tracking assumes.
  double refine_until_acceleration_sigma_m_s2 = 0.03;
};

/// The IMU state tracking needs once the IMU is initialised. g_w is expressed in the world frame
/// of the run (the map is not rotated at initialisation; a new map started after tracking loss is
/// started at the predicted pose in the same world frame, so g_w stays valid for every map and the
/// IMU stays initialised). generation grows at every update (first initialisation, each VI-BA
/// refinement), so tracking can tell a new estimate from an old one.
struct ImuState {
  bool initialised = false;
  imu::ImuBias bias;
  Vec3 g_w = Vec3(0.0, 0.0, -9.81);
  /// Posterior covariance of the world acceleration the IMU integrates, from the last
  /// (re)initialisation's window ((m/s^2)^2; optim::inertialAccelerationCovariance).
  Mat3 acceleration_covariance_w = Mat3::Zero();
  /// Initialised from the rest before the first map (ImuInit.FromPreMapRest), the map's own
  /// initialisation still to come: tracking keeps making keyframes at ImuInit.EarlyKeyFrames'
  /// interval until it (without them the map reached ImuInit.MinKeyFrames only after the first box
  /// arrived).
  bool awaiting_own_initialisation = false;
  std::uint64_t generation = 0;
};

/// The online camera-IMU time offset (LocalMapping.EstimateTimeOffset): the shift of the IMU
/// intervals against the camera stamps beyond IMU.TimeOffset (mapping/time_offset_estimator.h).
struct TimeOffsetStatus {
  bool estimated = false;    ///< an informative estimate has been accepted
  double shift_s = 0.0;      ///< current estimate (s; what tracking cuts with)
  double sigma_s = 0.0;      ///< its marginal sigma at the last accepted estimate (s)
  int updates = 0;           ///< accepted estimates
  int boundaries_moved = 0;  ///< keyframe IMU boundaries moved to follow them
  double first_estimate_t_s = -1.0;  ///< keyframe time of the first accepted estimate
};

struct LocalMapperCounters {
  int keyframes_processed = 0;
  int culled_keyframes = 0;
  int culled_points = 0;
  int dynamic_points = 0;       ///< deleted by the robust VIBA (beta below LocalMapping.MinPointBeta)
  int bow_updates = 0;          ///< keyframes whose BoW followed a refined Gamma
  int fused_points = 0;
  int local_ba_runs = 0;
  int imu_initialisations = 0;  ///< including refinements
};

class LocalMapper {
 public:
  /// `level_sigma2` is OrbExtractor::levelSigma2(); `timing` (may be nullptr) receives the stages
  /// "mapping.keyframe" (whole processing), "mapping.local_ba", "mapping.imu_init" (inertial-only
  /// initialisations), "mapping.imu_refine" (visual-inertial refinements).
  LocalMapper(map::Atlas& atlas, const LocalMapperOptions& options, std::vector<float> level_sigma2,
              TimingStats* timing = nullptr);
  LocalMapper(const LocalMapper&) = delete;
  LocalMapper& operator=(const LocalMapper&) = delete;
  ~LocalMapper();

  // ---- tracking thread ----
  /// Queues a keyframe (blocks when the queue is full) and aborts a running local BA so the new
  /// keyframe is taken soon (ORB-SLAM's abort flag).
  void insertKeyFrame(std::shared_ptr<map::KeyFrame> kf);
  std::size_t queuedKeyFrames() const;
  /// The latest IMU estimate.
  ImuState imuState() const;
  /// The current camera-IMU shift estimate (s; 0 until one is accepted). Lock-free: every frame.
  double timeShift() const;
  TimeOffsetStatus timeOffset() const;
  /// Replaces the published gravity with a full BA's (Loop.FullBaGravity; the loop thread calls it
  /// with local mapping paused). The biases stay: the BA wrote each keyframe's, and the newest
  /// keyframe's can be the one a long dead-reckoned gap bent. Ignored before the IMU is initialised.
  void setGravityFromFullBa(const Vec3& g_w);
  /// Before the run: the IMU state of a loaded atlas (gravity in its world, biases, the estimate's
  /// acceleration covariance) is published as initialised; the run's own keyframes then refine it
  /// (ImuInit refinements) instead of initialising from nothing. Call before the first keyframe.
  void seedImuState(const imu::ImuBias& bias, const Vec3& g_w, const Mat3& acceleration_covariance_w);

  // ---- synchronous use (tests, single-threaded runs) ----
  /// The whole processing of one keyframe, in the calling thread.
  void processKeyFrame(const std::shared_ptr<map::KeyFrame>& kf);

  // ---- mapping thread ----
  /// Processes queued keyframes until requestFinish(); then drains the queue and returns.
  /// Exceptions from processing are logged with the keyframe id and end the loop (System reports it).
  void run();
  void requestFinish();
  bool finished() const;

  // ---- loop closing ----
  /// Blocks until the mapper is between keyframes and holds there (aborting a running BA);
  /// returns at once when run() is not running. Tracking may go on inserting (queued).
  void pause();
  void resume();

  /// Called in the mapping thread after each processed keyframe (System forwards it to loop closing).
  void setKeyFrameProcessedCallback(std::function<void(const std::shared_ptr<map::KeyFrame>&)> callback);

  // ---- a run resumed from an atlas file (system/run_state.h) ----
  /// Local mapping's state between two keyframes, with its queue empty (single-threaded, or after
  /// run() returned): the IMU estimate and its refinement schedule, the camera-IMU time offset, the
  /// recent points under test, the processing index. Counters and the timeline are statistics and
  /// stay this run's.
  void writeState(map::ByteWriter& out) const;
  /// Restores it before the first keyframe; throws AtlasFileError (file, section, byte).
  void readState(map::ByteReader& in);

  LocalMapperCounters counters() const;
  /// One entry per processed keyframe, in processing order.
  std::vector<MappingTimelineEntry> timeline() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ltlo::mapping
