#pragma once
/// Tracker: the single-threaded visual(-inertial) front end. Each frame is predicted (constant
/// velocity on T_w_c, or the IMU once it is initialised), matched to the last frame by projection,
/// pose-optimised, then matched to the local map (keyframes covisible with the reference keyframe)
/// and pose-optimised again. Keyframes are inserted into the map with new RGB-D map points; an
/// optional synchronous local-mapping callback runs after each one (system/ replaces it by the
/// mapping thread).
///
/// The tracker works on the Atlas' active map, re-read every frame (a merge by the loop closer can
/// switch it). When the active map or its version() changes, the last frame's pose is re-derived
/// from its reference keyframe (latestPose_T_w_b(ref) * T_refb_c), so corrections and merges do
/// not break tracking; the constant-velocity model is relative and stays valid.
///
/// With the IMU initialised (and TrackingOptions::inertial_pose_optimisation), every frame's state
/// (pose, velocity, biases) is optimised with its static-weighted reprojection edges and the
/// preintegration link either to the last keyframe, whose state is held fixed (right after a
/// keyframe, a map change, a relocalisation or an IMU (re)initialisation, or when local mapping
/// changed the keyframe), or to the last frame, whose state enters with the marginal information of
/// its own optimisation (ORB-SLAM3's PoseInertialOptimizationLastFrame; an information filter over
/// frames). Velocities then come from this optimisation and from VI local BA, never from pose
/// differences. The predicted state carries its propagated information too: its standard
/// deviations widen the search windows after a gap.
///
/// Loss policy (loss_recovery.h): re-acquire -> relocalise -> the predicted state, a keyframe at
/// the IMU prediction or a new map, decided by a LossRecovery for every frame the motion model
/// does not track.
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/pose_gravity_check.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/map.h"
#include "ltlo/optim/pose_only_problem.h"
#include "ltlo/tracking/frame_segmenter.h"
#include "ltlo/tracking/imu_dead_reckoning.h"
#include "ltlo/tracking/loss_recovery.h"
#include "ltlo/tracking/tracker_options.h"

namespace bow {
class Vocabulary;
}
namespace ltlo::map {
class ByteReader;
class ByteWriter;
class KeyFrameRefs;
class RunKeyFrames;
}  // namespace ltlo::map

namespace ltlo::tracking {

/// kNotInitialised: no map yet (no pose on frames). kOk: the last frame was tracked (or relocalised,
/// or started a new map). kLost: the last frame was not tracked; it carries the predicted pose.
enum class TrackingState { kNotInitialised, kOk, kLost };
const char* trackingStateName(TrackingState state);

/// Per-frame numbers for logs and tests.
struct TrackingStats {
  int last_frame_matches = 0;  ///< matches to the last frame before optimisation
  int last_frame_inliers = 0;
  int local_map_matches = 0;   ///< all matches after the local-map search
  int inliers = 0;             ///< pose inliers after the local-map step
  double overlap = 0.0;        ///< share of the reference keyframe's points tracked
  bool used_imu = false;       ///< the IMU predicted the pose
  /// the IMU prediction started from the last keyframe (local mapping had updated its state)
  bool imu_from_keyframe = false;
  bool relocalised = false;    ///< the frame was relocalised (BoW + RANSAC)
  /// the lost frame re-acquired the active map by the IMU-guided search (Tracking.Reacquire; then
  /// relocalised is set too)
  bool reacquired = false;
  /// the tracked or recovered pose turned further from the gyroscope's rotation than
  /// Tracking.GyroRotationGate (before the IMU is initialised): the frame was made lost
  bool gyro_rejected = false;
  bool new_map = false;        ///< the frame started a new map
  /// the frame extended the active map at its IMU-predicted pose (lost, Tracking.MaxImuPositionSigma)
  bool map_extended = false;
  /// the inertial optimisation's link: 0 none (vision only), 1 the last keyframe, 2 the last frame
  int inertial_link = 0;
  /// standard deviations of the predicted state (largest axis; 0 without the IMU's information)
  double predicted_position_sigma_m = 0.0;
  double predicted_rotation_sigma_rad = 0.0;
  /// of the predicted velocity (m/s, largest axis), with the accelerometer-bias drift since the last
  /// tracked frame (sigma_a t)
  double predicted_velocity_sigma_m_s = 0.0;
  bool map_refreshed = false;  ///< the last frame's pose was re-derived (map version / active map)
  /// Localisation only: pose inliers among the last frame's temporary points (visual odometry,
  /// tracker_visual_odometry.cc), counted in `inliers` too; 0 when the map alone tracked it.
  int odometry_inliers = 0;
};

/// How much of a keyframe candidate's view the map already holds (KeyFrameOptions revisit_*).
struct MappedView {
  int inliers = 0;          ///< pose inliers
  int mapped_inliers = 0;   ///< of them, points seen by KF.RevisitMinObservers keyframes or more
  int static_with_depth = 0;  ///< static keypoints with depth
  /// of them, those in image cells (a coarse grid, kMappedViewGrid) without any pose inlier: the
  /// unmapped part of the view, whose points a keyframe would add. (Counting every unmatched
  /// keypoint would count the detector's misses on mapped ground too.)
  int unmatched = 0;
  double mappedShare() const { return inliers > 0 ? static_cast<double>(mapped_inliers) / inliers : 0.0; }
  double newShare() const { return static_with_depth > 0 ? static_cast<double>(unmatched) / static_with_depth : 1.0; }
};

/// The keyframe decision for one tracked frame (Tracker::decideKeyFrame).
struct KeyFrameDecision {
  bool interval = false;     ///< KF.MaxInterval (or the shorter interval before the IMU initialisation)
  bool low_overlap = false;  ///< KF.MaxOverlap
  bool weak = false;         ///< KF.MinTrackedPoints after KF.WeakMinInterval
  bool anchored = false;     ///< enough inliers to anchor a keyframe (KF.MinInliers[Inertial])
  /// a trigger held but the view is already mapped and KF.RevisitMaxInterval has not passed
  bool deferred_on_revisit = false;
  bool need = false;         ///< make the keyframe
  MappedView view;           ///< measured only when a trigger held and the revisit rule is on
};

/// Not thread-safe (the tracking thread owns it). Reads and writes the Atlas' active map through
/// its thread-safe API. Runs the loss policy's steps (RecoverySteps) for its LossRecovery.
class Tracker : private RecoverySteps {
 public:
  /// `level_sigma2` is OrbExtractor::levelSigma2() (keypoint variance per pyramid level).
  Tracker(map::Atlas& atlas, const TrackerOptions& options, std::vector<float> level_sigma2);

  /// Tracks `frame` (sets its pose, map-point matches, reference keyframe) and inserts a keyframe
  /// when needNewKeyFrame(). Returns the new state. Once initialised, every frame leaves with a
  /// pose (tracked, relocalised, or predicted when lost: see frameTracked()).
  TrackingState track(map::Frame& frame);

  TrackingState state() const { return state_; }
  /// Whether the last frame was tracked / relocalised / started a map (false: predicted pose).
  bool frameTracked() const { return frame_tracked_; }
  /// Whether the last frame's pose is the IMU's dead reckoning before the run's first map
  /// (Tracking.PreMapImuPose): in the world the first map will start in, with no keyframe yet.
  bool framePosedBeforeMap() const { return frame_posed_before_map_; }
  /// Frames tracked by the map's points alone (with Tracking.LocalisationOnly: not carried by the
  /// visual odometry or the IMU), over the run.
  int numFramesLocalisedInMap() const { return frames_localised_in_map_; }
  /// The IMU's prediction of the last frame's body pose, from the previous frame's state, before
  /// vision refined it (absent when the IMU did not predict: no IMU, not initialised, no samples).
  /// Before the IMU is initialised, with Tracking.StartCarriedLost, a lost frame's (and the next
  /// tracked frame's) prediction with the gyroscope's rotation stands for it.
  std::optional<SE3> imuPredicted_T_w_b() const {
    return imu_prediction_.valid ? std::optional<SE3>(imu_prediction_.state.T_w_b) : start_predicted_T_w_b_;
  }
  /// Camera pose of the last frame given to track() (tracked or predicted; identity before
  /// initialisation).
  SE3 T_w_c() const { return last_T_w_c_; }
  const TrackingStats& stats() const { return stats_; }

  /// Keyframe decision for the last tracked frame (KeyFrameOptions): overlap below max_overlap,
  /// or weak tracking, or max_interval_s since the last keyframe; and at least
  /// min_frames_between_keyframes frames since it.
  bool needNewKeyFrame() const { return decideKeyFrame().need; }
  /// The decision with its triggers and, on a revisit, the view's measure.
  KeyFrameDecision decideKeyFrame() const;
  /// The view of the last tracked frame against the map (MappedView).
  MappedView mappedView() const;
  /// Promotes the last tracked frame to a keyframe with its matches and new close map points,
  /// updates the covisibility graph and runs the local-mapping callback.
  std::shared_ptr<map::KeyFrame> createKeyFrame();

  /// Synchronous local mapping after each new keyframe (e.g. a test running localBundleAdjust).
  /// Runs in createKeyFrame() on the tracking thread with the active map.
  using LocalMappingCallback = std::function<void(map::Map&, const std::shared_ptr<map::KeyFrame>&)>;
  void setLocalMappingCallback(LocalMappingCallback callback) { local_mapping_ = std::move(callback); }

  /// Vocabulary for relocalisation (nullptr: none, no relocalisation). With it, frames that become
  /// keyframes get their BoW computed (if not already) so keyframes can enter the database; lost
  /// frames get theirs for the query. Not owned; must outlive the tracker.
  void setVocabulary(const bow::Vocabulary* vocabulary) { vocabulary_ = vocabulary; }

  /// The segmentation step (FrameSegmenter): called on every frame between the prediction and the
  /// matching; without one every frame keeps the one-static-cluster seam. System creates it from
  /// the settings; the caller of track() calls segmenter()->begin(input) before building the frame.
  void setSegmenter(std::unique_ptr<FrameSegmenter> segmenter) { segmenter_ = std::move(segmenter); }
  FrameSegmenter* segmenter() { return segmenter_.get(); }
  /// Outcome of the last frame's segmentation step.
  const SegmentationOutcome& segmentationOutcome() const { return segmentation_outcome_; }

  /// IMU hook (system/ calls it after IMU initialisation): from now on frames carrying
  /// imu_from_last_frame are predicted by preintegration (and pose-optimised with the inertial link
  /// when inertial_pose_optimisation). The world must be gravity-aligned (g_w) by then. May be
  /// called again with refined values (they replace the old ones).
  /// `acceleration_sigma_m_s2` is the (re)initialisation's own uncertainty of the world
  /// acceleration it integrates (optim::accelerationSigma); the prediction's position sigma uses
  /// the larger of it and Tracking.AccBiasSigma.
  /// `early_keyframes`: the estimate is the one from the rest before the map, the map's own still to
  /// come (mapping::ImuState::awaiting_own_initialisation): keyframes stay at the early interval.
  void setImuInitialised(const imu::ImuBias& bias, const Vec3& g_w, double acceleration_sigma_m_s2 = 0.0,
                         bool early_keyframes = false);
  bool imuInitialised() const { return imu_initialised_; }
  /// Gravity in the world frame the IMU prediction uses (m/s^2; meaningful once imuInitialised()).
  const Vec3& g_w() const { return g_w_; }
  /// The bias new frames are preintegrated at: the last optimised frame's (inertial optimisation),
  /// else the IMU initialisation's or the last keyframe's.
  const imu::ImuBias& bias() const { return bias_; }
  /// Marginal information of the last frame's state [dphi; drho; dv; db_g; db_a] (inertial
  /// optimisation or IMU-only prediction); nullopt when it has none (vision only, before the IMU).
  std::optional<Mat15> stateInformation() const;

  /// Keyframes created by this tracker (all maps).
  int numKeyFrames() const { return num_keyframes_; }
  /// Tracked frames whose keyframe the revisit rule deferred (KF.RevisitMaxInterval).
  int numKeyFramesDeferredOnRevisit() const { return keyframes_deferred_on_revisit_; }
  map::KeyFrameId referenceKeyFrame() const { return reference_kf_; }
  /// Reference keyframe of the last frame (nullptr before initialisation); its pose and the last
  /// frame's pose are consistent (the frame's pose was estimated against the map holding it).
  std::shared_ptr<map::KeyFrame> referenceKeyFramePtr() const { return reference_kf_ptr_; }
  /// Maps started by the loss policy (the first map is not counted).
  int numMapsCreated() const { return loss_.mapsCreated() + (loaded_start_new_map_ ? 1 : 0); }
  /// Declares tracking lost (the next frame goes through the lost path: motion model with wide
  /// windows, relocalisation). For tests and resets; no-op before initialisation.
  void forceLost();

  /// The tracker's state between two frames, for a run resumed from an atlas file
  /// (map/run_state_io.h; tracker_state_io.cc): everything a later frame reads. The keyframes it
  /// holds go through `refs` (culled ones included). The segmenter's state is its own.
  void writeState(map::ByteWriter& out, map::KeyFrameRefs& refs) const;
  /// Restores it on a tracker built with the saved run's options, in the restored atlas (before
  /// its first frame); the last frame's BoW is recomputed with the vocabulary set before. Throws
  /// AtlasFileError (file, section, byte) on a malformed record.
  void readState(map::ByteReader& in, const map::RunKeyFrames& keyframes);

 private:
  /// What the IMU tells about the current frame before matching (tracker_inertial.cc).
  struct ImuPrediction {
    bool valid = false;  ///< the IMU predicted the state
    optim::InertialState state;
    /// The inertial optimisation's link (absent: the IMU only predicts, or no usable link).
    std::optional<optim::InertialLink> link;
    int link_kind = 0;  ///< TrackingStats::inertial_link
    /// Information of the predicted state (valid with a link).
    Mat15 information = Mat15::Zero();
  };
  /// A frame's optimised (or predicted) state and its marginal information.
  struct StateInformation {
    bool valid = false;
    Mat15 information = Mat15::Zero();
  };

  TrackingState initialise(map::Frame& frame);
  /// IMU since the last keyframe, appended across lost frames (re-anchored while lost for long).
  void accumulateImuSinceKeyFrame(const map::Frame& frame);
  /// Segmentation step at the prediction; returns the prediction, refined by it where it applies.
  SE3 segmentAtPrediction(map::Frame& frame, const SE3& T_w_b_pred);
  /// The Tracker's state the loss policy reads and sets for this frame.
  LossContext lossContext(const map::Frame& frame, bool was_lost);
  /// A frame tracked (or recovered) with `inliers` pose inliers: map-point counters, the stretch,
  /// overlap, the constant-velocity model, the last frame.
  void recordTrackedFrame(map::Frame& frame, int inliers, bool was_lost);
  /// Re-derives the last frame's pose from its reference keyframe after a map change.
  void refreshAfterMapChange(map::Map& map);
  /// Predicted body pose of `frame` (sets its velocity and bias with the IMU; fills imu_prediction_).
  SE3 predictPose_T_w_b(map::Frame& frame);
  /// IMU prediction and inertial link from the last keyframe or the last frame (tracker_inertial.cc).
  ImuPrediction predictWithImu(const map::Frame& frame);
  /// The motion prior of the segmentation step for `frame` predicted at T_w_b_pred (tracker_inertial.cc).
  MotionPrior motionPrior(const map::Frame& frame, const SE3& T_w_b_pred) const;
  /// Runs the segmentation step (no-op without a segmenter); returns the refined state if any.
  SegmentationOutcome segment(map::Frame& frame, const MotionPrior& prior);
  /// Motion-model tracking: last-frame search, local map; returns pose inliers.
  int trackWithMotionModel(map::Frame& frame, const SE3& T_w_b_pred);
  // ---- RecoverySteps (loss_recovery.h): the loss policy's searches and map changes ----
  /// Guided re-acquisition (Tracking.Reacquire, tracker_reacquire.cc).
  int reacquire(map::Frame& frame, const SE3& T_w_b_pred, double sigma_position_m) override;
  /// Relocalisation in the active map (tracker_reacquire.cc).
  int relocalise(map::Frame& frame) override;
  void holdPrediction(map::Frame& frame, const SE3& T_w_b_pred, const Vec3& v_w_b_pred) override;
  /// The frame's static keypoints that match nothing become map points of a keyframe at its
  /// (IMU-predicted) pose in the active map (tracker_keyframe.cc).
  void extendMapAtPrediction(map::Frame& frame) override;
  void initialiseNewMap(map::Frame& frame) override;
  void recordFramePose(const map::Frame& frame) override;
  /// track() but for localisation only's IMU window: predict -> segment -> match -> recover ->
  /// keyframe.
  TrackingState trackFrame(map::Frame& frame);
  /// A frame before the first pose of a run in a loaded atlas: relocalised in the loaded maps, or
  /// after tracking.loaded_atlas_new_map_after_s a new map started (tracker_loaded_start.cc).
  TrackingState startInLoadedAtlas(map::Frame& frame);
  /// Relocalisation in each map of the atlas with content, the active one first; the map it
  /// succeeds in becomes active. Pose inliers (0: not relocalised).
  int relocaliseInAnyMap(map::Frame& frame);
  /// The tracker's state from a relocalised first frame (no keyframe made): initialise()'s
  /// bookkeeping in the map the frame was relocalised in.
  void startAtRelocalisedFrame(map::Frame& frame, int inliers);
  /// After each tracked frame while the velocity is unknown: the anchor frame's velocity v0 from
  /// p_i = p_0 + v0 dt_i + g dt_i^2 / 2 + R_0 dp_0i (least squares over the frames since the anchor,
  /// the IMU preintegrated at the deferred bias), this frame's as v0 + g dt + R_0 dv_0i; after
  /// kStartVelocityBaselineS the deferred IMU state is applied with it.
  void estimateStartVelocity(map::Frame& frame, bool re_anchor);
  // ---- localisation only: visual odometry on temporary points (tracker_visual_odometry.cc) ----
  /// When the map alone gives fewer than minInliers() (`map_inliers`): the frame matched by
  /// projection to the last tracked frame's temporary points and the pose re-optimised with both;
  /// returns the inliers of that optimisation (0: not run). First tries to re-acquire the map
  /// around the pose within the odometry's drift.
  int trackWithOdometry(map::Frame& frame, int map_inliers);
  /// After a tracked frame: its static keypoints with depth that match no map point become the
  /// next frame's temporary points (in the world, at the frame's pose; never in the map).
  void keepOdometryPoints(const map::Frame& frame);
  /// Localisation only, after every frame: the frames the map localised become nodes (one per
  /// kBiasNodeIntervalS) of a window linked by their preintegrations, and every second the biases
  /// and gravity are re-estimated over it by the inertial-only optimisation with the nodes' poses
  /// held (optim::initializeImu), as local mapping's IMU refinements do on keyframes
  /// (tracker_localisation_imu.cc). The loaded map's biases are another power-up's: a difference of
  /// 0.1 m/s^2 integrates to metres over seconds of occlusion.
  void updateLocalisationImu(const map::Frame& frame, bool map_localised);
  /// After a relocalisation or re-acquisition: the frame's state re-optimised with the IMU link to
  /// the previous (predicted) frame, whose prior keeps velocity and biases only. Returns the
  /// inliers of that optimisation (0 when there is no link).
  int optimiseStateAfterGap(map::Frame& frame);
  int matchLastFrame(map::Frame& frame, double radius_scale);
  int searchLocalMap(map::Frame& frame);
  /// Search half window (px) for a point predicted at depth_m: base_px, widened to search_sigmas
  /// standard deviations of the predicted reprojection (IMU prediction after a gap).
  float searchRadius(float base_px, double depth_m, double fx_px) const;
  /// Pose-only optimisation over frame.map_points, with the inertial link when given (the
  /// pose-inertial optimisation); marks outliers; returns inliers. Sets the frame's state and
  /// frame_information_.
  int optimisePose(map::Frame& frame, const SE3& T_w_b_init, bool drop_outliers,
                   const optim::InertialLink* link = nullptr);
  /// The link of the inertial optimisation (nullptr: vision only).
  const optim::InertialLink* inertialLink() const;
  /// Inlier threshold of the current frame (with or without the inertial optimisation).
  int minInliers() const;
  void updateLocalMap(const map::Frame& frame);
  int addNewMapPoints(map::KeyFrame& kf, map::Frame& frame);

  map::Map& activeMap() { return atlas_.activeMap(); }

  map::Atlas& atlas_;
  const bow::Vocabulary* vocabulary_ = nullptr;
  TrackerOptions options_;
  std::vector<float> level_sigma2_;
  LocalMappingCallback local_mapping_;
  std::unique_ptr<FrameSegmenter> segmenter_;
  SegmentationOutcome segmentation_outcome_;

  TrackingState state_ = TrackingState::kNotInitialised;
  TrackingStats stats_;
  std::optional<map::Frame> last_frame_;  ///< last successfully tracked frame
  SE3 last_T_w_c_;
  std::optional<SE3> velocity_T_last_cur_;  ///< constant-velocity model: T_c_last^-1 motion
  double velocity_dt_s_ = 0.0;              ///< the time that motion took (s)
  int frames_since_keyframe_ = 0;
  /// tracked again after a loss, no keyframe since (KF.MinInliersInertial applies)
  bool resumed_without_keyframe_ = false;
  double last_keyframe_t_s_ = 0.0;
  map::KeyFrameId reference_kf_;
  std::shared_ptr<map::KeyFrame> reference_kf_ptr_;
  map::KeyFrameId last_kf_;
  std::shared_ptr<map::KeyFrame> last_kf_ptr_;
  /// The last keyframe's state as the tracker last saw it: a difference means local mapping (or a
  /// correction) updated it, and the IMU then predicts from the keyframe (ORB-SLAM3's map-updated
  /// prediction) instead of the last frame.
  SE3 last_kf_T_w_b_seen_;
  Vec3 last_kf_v_w_b_seen_ = Vec3::Zero();
  imu::ImuBias last_kf_bias_seen_;
  bool frame_tracked_ = false;
  // Map-change detection: the active map and its version seen by the last frame.
  map::MapId map_id_;
  std::uint64_t map_version_ = 0;
  /// The last frame's camera relative to its reference keyframe's body: T_refb_c.
  SE3 T_refb_c_last_;
  // The previous frame's state (tracked or predicted), for chaining predictions while lost.
  SE3 prev_T_w_b_;
  Vec3 prev_v_w_b_ = Vec3::Zero();
  double prev_t_s_ = 0.0;
  double last_tracked_t_s_ = 0.0;
  LossRecovery loss_;  ///< the loss policy and the IMU-carried stretch
  int num_keyframes_ = 0;
  int keyframes_deferred_on_revisit_ = 0;
  std::vector<map::KeyFrameId> local_keyframes_;
  std::vector<map::MapPointId> local_points_;
  /// Scratch of the searches by projection, reused frame to frame: the map points looked up under
  /// one map lock (Map::mapPointsInto) and a keypoint area.
  std::vector<std::shared_ptr<map::MapPoint>> point_scratch_;
  std::vector<int> area_scratch_;

  /// A run in a loaded atlas that has no pose yet (TrackerOptions::start_in_loaded_atlas), and the
  /// time of its first frame.
  bool loaded_start_pending_ = false;
  std::optional<double> loaded_start_t_s_;
  bool loaded_start_new_map_ = false;  ///< such a run started a new map (not relocalised in time)
  /// Such a run's velocity is unknown when its first frame is relocalised: an IMU state handed over
  /// before it is known (the loaded atlas's, setImuInitialised) waits in deferred_imu_ until
  /// estimateStartVelocity() has fitted the velocity to kStartVelocityBaselineS of tracked frames.
  struct DeferredImu {
    imu::ImuBias bias;
    Vec3 g_w = Vec3::Zero();
    double acceleration_sigma_m_s2 = 0.0;
  };
  bool velocity_unknown_ = false;
  std::optional<DeferredImu> deferred_imu_;
  struct StartVelocityFit {
    SE3 T_w_b0;              ///< the anchor frame's body pose
    double t0_s = 0.0;
    std::optional<imu::Preintegrated> imu_since_anchor;
    Vec3 weighted_v0 = Vec3::Zero();  ///< sum of dt^2 * v0 samples
    double weight = 0.0;
  };
  std::optional<StartVelocityFit> start_velocity_;

  /// Localisation only: the last tracked frame's temporary points (never in the map) and the
  /// current frame's matches to them, which optimisePose adds to its observations.
  struct OdometryPoint {
    Vec3 p_w = Vec3::Zero();
    features::Descriptor descriptor{};
    int octave = 0;
  };
  std::vector<OdometryPoint> odometry_points_;
  std::vector<optim::PoseObservation> odometry_observations_;
  std::vector<bool> odometry_inlier_;  ///< per odometry observation, set by optimisePose
  /// trackWithOdometry's per-frame buffers, kept so a frame allocates nothing once they have grown.
  std::vector<int> odometry_best_point_;
  std::vector<int> odometry_best_distance_;
  std::vector<map::MapPointId> odometry_matches_before_;
  std::vector<bool> odometry_outliers_before_;
  /// The last frame the map alone localised (s), and frames so localised in the run.
  double last_map_localised_t_s_ = 0.0;
  int frames_localised_in_map_ = 0;
  /// The map localised the current frame (set by trackWithOdometry / the start's relocalisation).
  bool frame_map_localised_ = false;
  /// The window of updateLocalisationImu: node poses and times, pims[k] from node k to k + 1, the
  /// IMU since the newest node.
  struct LocalisationImuWindow {
    std::vector<SE3> T_w_b;
    std::vector<double> t_s;
    std::vector<std::shared_ptr<const imu::Preintegrated>> pims;
    std::optional<imu::Preintegrated> since_newest;
    double last_estimate_t_s = -1.0;
  };
  LocalisationImuWindow localisation_imu_;

  bool imu_initialised_ = false;
  bool early_keyframes_after_init_ = false;  ///< setImuInitialised's early_keyframes
  /// The last (re)initialisation's acceleration sigma (m/s^2, setImuInitialised).
  double init_acceleration_sigma_m_s2_ = 0.0;
  imu::ImuBias bias_;
  Vec3 g_w_ = Vec3(0.0, 0.0, -9.81);
  /// IMU since the last keyframe (appended in place, O(1) per frame; shared with the inertial
  /// optimisation's keyframe link while it runs).
  std::shared_ptr<imu::Preintegrated> imu_since_keyframe_;
  /// The preintegration since the last keyframe was re-anchored while lost: the next keyframe
  /// starts a new IMU chain.
  bool imu_chain_broken_ = false;

  // ---- inertial optimisation (tracker_inertial.cc) ----
  /// The next frame links to the last keyframe (state fixed) instead of the last frame.
  bool link_to_keyframe_ = true;
  /// The last keyframe's velocity and biases are inertial estimates (else the keyframe link leaves
  /// its velocity free and uses the tracker's bias).
  bool last_kf_inertial_ = false;
  /// Tracking.NewMapVelocityPrior: the first keyframe of a new map started after an IMU-carried
  /// loss, and the information of its dead-reckoned velocity (the carried prediction's velocity
  /// marginal), the prior of the keyframe link's free velocity. Not saved with the tracker's state
  /// (a run resumed before the map's second keyframe leaves that velocity free).
  map::KeyFrameId new_map_velocity_kf_;
  Mat3 new_map_velocity_information_ = Mat3::Zero();
  ImuPrediction imu_prediction_;
  /// The current frame's state information (set by optimisePose and the lost path).
  StateInformation frame_information_;
  /// Standard deviation of the frame's position along its least constrained direction from the last
  /// pose optimisation's marginal information, m (infinity: unconstrained; Tracking.StartMotionCheck)
  double pose_sigma_m_ = std::numeric_limits<double>::infinity();
  /// The previous frame's (the link's "last frame").
  StateInformation prev_information_;
  imu::ImuBias prev_bias_;

  // ---- standstill (tracker_standstill.cc, issue 32) ----
  /// Feeds the frame's IMU samples to the zero-velocity test; sets still_ and, on the first still
  /// frame, the bias held while still.
  void updateStandstill(const map::Frame& frame);
  /// The frame is held at rest (Tracking.Zupt, the test says rest, tracking has a pose).
  bool holdingStill() const;
  /// Tracking.ZuptVisualCheck: the frame's static matches agree with the held pose (true when off
  /// or when fewer than 10 static matches leave the view without a say).
  bool stillConfirmedByView(const map::Frame& frame);
  /// The zero-velocity update: the frame keeps the previous frame's pose (corrected with it by map
  /// changes), zero velocity and the held bias, is tracked whatever its matches, and makes the rest
  /// keyframe when due (TrackerOptions::rest_keyframe); never another keyframe.
  TrackingState trackStill(map::Frame& frame, int inliers, bool was_lost);
  bool restKeyFrameDue(const map::Frame& frame) const;

  std::optional<imu::ZeroVelocityDetector> zero_velocity_;
  bool still_ = false;               ///< the zero-velocity test says rest at this frame
  double still_from_t_s_ = 0.0;      ///< oldest sample of the window that first said rest
  imu::ImuBias still_bias_;          ///< the bias held while still
  bool rest_keyframe_made_ = false;  ///< the rest keyframe for the IMU initialisation was made
  /// Held at rest at the last frame or the one before: the IMU links to the last frame (its state
  /// and the rest prior), not to the keyframe from before the stop.
  bool link_last_frame_after_rest_ = false;

  // ---- occluded start (issue 32; tracker_start.cc) ----
  /// The points of `kf`, the first keyframe of a run's first map, made before any motion was seen,
  /// become provisional for Tracking.StartProvisional seconds.
  void makeStartPointsProvisional(const map::KeyFrame& kf);
  /// After every frame with a pose: each provisional point is projected with it; where the frame's
  /// depth there matches the point's, the cluster's gamma is a vote (dynamic or static); a point
  /// with Tracking.StartDynamicVotes more dynamic votes than static ones is erased from the map.
  void checkProvisionalPoints(const map::Frame& frame);
  /// Tracking.StartReacquireSpeed: the position sigma of a lost frame's guided re-acquisition
  /// before the IMU is initialised (infinity: none, or the IMU is initialised).
  double startReacquireSigma(const map::Frame& frame) const;
  /// Before the IMU is initialised, a lost frame's predicted rotation from the gyroscope
  /// (Tracking.StartReacquireSpeed): R_w_b of the previous frame times the frame's delta R, the
  /// camera centre kept. Returns `T_w_b_pred` unchanged otherwise.
  SE3 startGyroRotation(const map::Frame& frame, const SE3& T_w_b_pred) const;
  /// Tracking.StartRecoveryCutsImu: after a frame recovered (relocalised or re-acquired) within the
  /// start window, before the IMU is initialised, the next keyframe starts a new IMU chain; and
  /// Tracking.StartRecoveryGauge: a frame relocalised on another keyframe than the gauge makes it the
  /// map's gauge, and the keyframes made before it are erased.
  void onStartRecovery(const map::Frame& frame);
  /// Tracking.StartMotionCheck: every frame tracked (not recovered) within the start window before
  /// the IMU is initialised adds its pose and IMU interval to start_motion_; a window whose gravity
  /// disagrees recovers the frame like a relocalised one (the IMU chain cut with
  /// Tracking.StartRecoveryCutsImu, the gauge moved with Tracking.StartRecoveryGauge). Any other
  /// frame starts the check afresh.
  void checkStartMotion(const map::Frame& frame, TrackingState state);
  /// Tracking.StartRecoveryCutsImu: the next keyframe starts a new IMU chain (`why` for the log).
  void cutStartImuChain(const map::Frame& frame, const char* why);
  /// Tracking.StartRecoveryGauge: the reference keyframe becomes the map's gauge and the keyframes
  /// made before the frame are erased (`why` for the log).
  void moveStartGauge(const map::Frame& frame, const char* why);
  /// Erases the keyframes older than `recovered_t_s` other than the reference keyframe
  /// (Tracking.StartRecoveryGauge); returns how many.
  int eraseKeyFramesBefore(map::Map& active, double recovered_t_s);
  struct ProvisionalPoint {
    map::MapPointId id;
    int dynamic_votes = 0;
    int static_votes = 0;
  };
  std::vector<ProvisionalPoint> provisional_points_;
  /// Tracking.StartMotionCheck's poses and gravity estimates since the last reset
  imu::PoseGravityCheck start_motion_;
  int start_motion_recoveries_ = 0;  ///< frames recovered by it
  double provisional_from_t_s_ = 0.0;   ///< the first keyframe's time
  /// End of the start window (the first keyframe's time + Tracking.StartProvisional; -infinity: none)
  double start_window_end_t_s_ = -std::numeric_limits<double>::infinity();
  /// This frame's prediction with the gyroscope's rotation while lost before the IMU is
  /// initialised (Tracking.StartCarriedLost; set afresh every frame)
  std::optional<SE3> start_predicted_T_w_b_;
  /// The first frame of the current wait for a view good enough to start a map (NaN: not waiting).
  double init_wait_since_t_s_ = std::numeric_limits<double>::quiet_NaN();
  // ---- before the first map (Tracking.PreMapImuPose, issue 32) ----
  /// Poses the frame by the IMU's dead reckoning since the run's first frame (the frame waits for a
  /// view to start the first map, or is the one that starts it).
  void poseBeforeFirstMap(map::Frame& frame);
  /// The dead reckoning while no map was started yet (empty before the first frame and after).
  std::optional<ImuDeadReckoning> pre_map_;
  /// A map was started (or the run started in a loaded atlas or from a saved state): no more
  /// dead reckoning from the first frame.
  bool first_map_started_ = false;
  bool frame_posed_before_map_ = false;     ///< this frame's pose is pre_map_'s
  bool pre_map_position_held_logged_ = false;  ///< said once that only the orientation is kept
  double pre_map_t0_s_ = 0.0;                  ///< the run's first frame
  int provisional_erased_ = 0;          ///< erased so far
};

}  // namespace ltlo::tracking
