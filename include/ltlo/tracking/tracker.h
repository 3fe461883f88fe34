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
/// Loss policy: a frame with fewer pose inliers than needed (Tracking.MinInliers by vision,
/// Tracking.MinInliersImu with the inertial optimisation) is not tracked (kLost) and gets the
/// predicted state (with the IMU: the IMU-only prediction and its propagated information; else the
/// constant-velocity model for up to max_prediction_s after the last tracked frame, then the last
/// pose held). While lost, every frame first tries the motion model (doubled windows), then
/// relocalisation in the active map (with a vocabulary); with the IMU's link and
/// Tracking.Reacquire, the guided re-acquisition comes before the relocalisation: the keyframes
/// around the IMU-predicted pose are projected with it, matched in windows of the predicted
/// uncertainty and verified by a 3-D-3-D RANSAC pose gated by the prediction (tracker_reacquire.cc).
/// Lost for new_map_after_s and the frame has
/// enough static keypoints: with the IMU and the predicted position still within
/// Tracking.MaxImuPositionSigma, a keyframe extends the active map at the predicted pose (the IMU
/// chain continues); otherwise Atlas::createNewMap() and a new map is initialised at the frame's
/// predicted pose (same world frame; the old map is kept for merging).
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/map.h"
#include "ltlo/optim/pose_only_problem.h"
#include "ltlo/place/guided_place_match.h"
#include "ltlo/tracking/frame_segmenter.h"
#include "ltlo/tracking/relocaliser.h"

namespace bow {
class Vocabulary;
}

namespace ltlo::tracking {

/// kNotInitialised: no map yet (no pose on frames). kOk: the last frame was tracked (or relocalised,
/// or started a new map). kLost: the last frame was not tracked; it carries the predicted pose.
enum class TrackingState { kNotInitialised, kOk, kLost };
const char* trackingStateName(TrackingState state);

struct TrackerOptions {
  KeyFrameOptions keyframe;  ///< overlap / weak-tracking / interval decision (core settings)
  /// inertial pose optimisation, inlier thresholds, new-map policy, IMU re-anchoring, virtual
  /// baseline of the RGB-D edges (core settings, Tracking.* / RGBD.*)
  TrackingOptions tracking;
  /// static keypoints with depth needed by the first frame to start a map
  int min_init_features = 100;
  /// fewest frames between keyframes (0: a keyframe may follow the previous one directly)
  int min_frames_between_keyframes = 0;
  /// Longest keyframe interval while the IMU is used but not yet initialised, s (0: only
  /// keyframe.max_interval_s). The initialisation waits for ImuInit.MinKeyFrames keyframes spanning
  /// ImuInit.MinTime; System sets MinTime / (MinKeyFrames - 1) so the map can initialise when
  /// MinTime has passed, not only after MinKeyFrames x KF.MaxInterval (an early occlusion would
  /// otherwise meet a vision-only tracker).
  double imu_init_keyframe_interval_s = 0.0;
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
  /// With the IMU, a search window is at least this many standard deviations of the predicted
  /// reprojection (from the predicted state's covariance), up to max_search_radius_px.
  double search_sigmas = 3.0;
  double max_search_radius_px = 80.0;
  /// ratio test of the local-map search (best vs second best on the same level)
  double local_map_ratio = 0.8;
  /// local keyframes at most
  int max_local_keyframes = 60;
  /// Without the inertial optimisation (the ablation), an IMU-predicted frame's velocity is the
  /// predicted one corrected by this share of (finite difference of the optimised positions -
  /// predicted): a complementary filter (1: the plain finite difference). Unused with it.
  double velocity_gain = 0.1;

  // ---- tracking loss ----
  /// While lost without the IMU, the constant-velocity model keeps predicting for this long after
  /// the last tracked frame (s); later frames hold the last predicted pose.
  double max_prediction_s = 1.0;
  /// Relocalisation is accepted with at least this many pose inliers after the local-map search.
  int min_relocalisation_inliers = 50;
  RelocalisationOptions relocalisation;
};

/// The guided search of the re-acquisition (Tracking.Reacquire*, the local-map window floor and
/// keyframes, the descriptor and RANSAC thresholds), without its sigmas and seed; the loop
/// closer's rejoin (Loop.Rejoin) searches with the same settings.
place::GuidedPlaceMatchOptions reacquireSearchOptions(const TrackerOptions& options);

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
  bool new_map = false;        ///< the frame started a new map
  /// the frame extended the active map at its IMU-predicted pose (lost, Tracking.MaxImuPositionSigma)
  bool map_extended = false;
  /// the inertial optimisation's link: 0 none (vision only), 1 the last keyframe, 2 the last frame
  int inertial_link = 0;
  /// standard deviations of the predicted state (largest axis; 0 without the IMU's information)
  double predicted_position_sigma_m = 0.0;
  double predicted_rotation_sigma_rad = 0.0;
  bool map_refreshed = false;  ///< the last frame's pose was re-derived (map version / active map)
};

/// Not thread-safe (the tracking thread owns it). Reads and writes the Atlas' active map through
/// its thread-safe API.
class Tracker {
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
  /// The IMU's prediction of the last frame's body pose, from the previous frame's state, before
  /// vision refined it (absent when the IMU did not predict: no IMU, not initialised, no samples).
  std::optional<SE3> imuPredicted_T_w_b() const {
    return imu_prediction_.valid ? std::optional<SE3>(imu_prediction_.state.T_w_b) : std::nullopt;
  }
  /// Camera pose of the last frame given to track() (tracked or predicted; identity before
  /// initialisation).
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
  void setImuInitialised(const imu::ImuBias& bias, const Vec3& g_w, double acceleration_sigma_m_s2 = 0.0);
  bool imuInitialised() const { return imu_initialised_; }
  /// The bias new frames are preintegrated at: the last optimised frame's (inertial optimisation),
  /// else the IMU initialisation's or the last keyframe's.
  const imu::ImuBias& bias() const { return bias_; }
  /// Marginal information of the last frame's state [dphi; drho; dv; db_g; db_a] (inertial
  /// optimisation or IMU-only prediction); nullopt when it has none (vision only, before the IMU).
  std::optional<Mat15> stateInformation() const;

  /// Keyframes created by this tracker (all maps).
  int numKeyFrames() const { return num_keyframes_; }
  map::KeyFrameId referenceKeyFrame() const { return reference_kf_; }
  /// Reference keyframe of the last frame (nullptr before initialisation); its pose and the last
  /// frame's pose are consistent (the frame's pose was estimated against the map holding it).
  std::shared_ptr<map::KeyFrame> referenceKeyFramePtr() const { return reference_kf_ptr_; }
  /// Maps started by the loss policy (the first map is not counted).
  int numMapsCreated() const { return maps_created_; }
  /// Declares tracking lost (the next frame goes through the lost path: motion model with wide
  /// windows, relocalisation). For tests and resets; no-op before initialisation.
  void forceLost();

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
  /// Re-derives the last frame's pose from its reference keyframe after a map change.
  void refreshAfterMapChange(map::Map& map);
  /// Predicted body pose of `frame` (sets its velocity and bias with the IMU; fills imu_prediction_).
  SE3 predictPose_T_w_b(map::Frame& frame);
  /// IMU prediction and inertial link from the last keyframe or the last frame (tracker_inertial.cc).
  ImuPrediction predictWithImu(const map::Frame& frame);
  /// The motion prior of the segmentation step for `frame` predicted at T_w_b_pred.
  MotionPrior motionPrior(const map::Frame& frame, const SE3& T_w_b_pred) const;
  /// Runs the segmentation step (no-op without a segmenter); returns the refined state if any.
  SegmentationOutcome segment(map::Frame& frame, const MotionPrior& prior);
  /// Motion-model tracking: last-frame search, local map; returns pose inliers.
  int trackWithMotionModel(map::Frame& frame, const SE3& T_w_b_pred);
  /// Relocalisation in the active map; returns pose inliers (0 when not relocalised).
  int relocalise(map::Frame& frame);
  /// Guided re-acquisition of the active map by a lost frame at the IMU prediction T_w_b_pred
  /// (Tracking.Reacquire, tracker_reacquire.cc); returns pose inliers (0 when not re-acquired).
  int reacquire(map::Frame& frame, const SE3& T_w_b_pred);
  /// After a relocalisation or re-acquisition: the frame's state re-optimised with the IMU link to
  /// the previous (predicted) frame, whose prior keeps velocity and biases only. Returns the
  /// inliers of that optimisation (0 when there is no link).
  int optimiseStateAfterGap(map::Frame& frame);
  /// Lost frame: the predicted state, then a new map or a keyframe at the prediction when due.
  void handleLostFrame(map::Frame& frame, const SE3& T_w_b_pred, const Vec3& v_w_b_pred);
  /// Bookkeeping of a frame that leaves track() with a pose (tracked or predicted).
  void recordFramePose(const map::Frame& frame);
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
  /// The frame's static keypoints that match nothing become map points of a keyframe at its
  /// (IMU-predicted) pose in the active map; the IMU chain continues.
  void extendMapAtPrediction(map::Frame& frame);
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
  int maps_created_ = 0;
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
  /// IMU-carried stretch: keyframes placed at the IMU prediction (extendMapAtPrediction) are not a
  /// fix in the map's world: the stretch lasts from the last frame tracked against the map as it
  /// was before it (anchored_t_s_) until a frame matches at least minInliers() points older than
  /// the stretch's first point (carried_first_point_; invalid when no stretch is open).
  double anchored_t_s_ = 0.0;
  map::MapPointId carried_first_point_;
  /// The position sigma the loss policy compares with Tracking.MaxImuPositionSigma (m).
  double carried_position_sigma_m_ = std::numeric_limits<double>::infinity();
  /// Over an open stretch, the loss policy's sigma integrates the acceleration error from the last
  /// visual fix (carried_fix_t_s_, sigma carried_fix_sigma_m_): at first the last anchored frame;
  /// once frames have tracked the points of a keyframe placed at the prediction for
  /// kCarriedFixSeconds in a row, vision observes the velocity again and that keyframe's placement
  /// sigma (carried_placement_sigma_m_) becomes the fix, renewed by every further tracked frame.
  /// Points placed and lost again within a few frames do not stop the drift.
  static constexpr double kCarriedFixSeconds = 0.5;
  double carried_placement_sigma_m_ = 0.0;
  double carried_fix_sigma_m_ = 0.0;
  double carried_fix_t_s_ = 0.0;
  /// first frame of the current run of tracked frames (NaN after a lost frame)
  double tracked_run_start_s_ = std::numeric_limits<double>::quiet_NaN();
  int num_keyframes_ = 0;
  std::vector<map::KeyFrameId> local_keyframes_;
  std::vector<map::MapPointId> local_points_;

  bool imu_initialised_ = false;
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
  ImuPrediction imu_prediction_;
  /// The current frame's state information (set by optimisePose and the lost path).
  StateInformation frame_information_;
  /// The previous frame's (the link's "last frame").
  StateInformation prev_information_;
  imu::ImuBias prev_bias_;
};

}  // namespace ltlo::tracking
