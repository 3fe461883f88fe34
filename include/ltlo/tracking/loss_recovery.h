#pragma once
/// LossRecovery: the Tracker's loss-and-recovery policy, one object (tracking/loss_recovery.cc).
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
///
/// The policy decides and keeps the IMU-carried stretch; the searches and the map changes it
/// decides are the Tracker's own steps (RecoverySteps), the Tracker's state it reads and sets is
/// handed over per frame (LossContext). Not thread-safe (the tracking thread owns it, inside the
/// Tracker).
#include <limits>
#include <memory>
#include <optional>

#include "ltlo/core/lie.h"
#include "ltlo/imu/preintegration.h"
#include "ltlo/map/atlas.h"
#include "ltlo/map/frame.h"
#include "ltlo/map/keyframe.h"
#include "ltlo/tracking/tracker_options.h"

namespace ltlo::map {
class ByteReader;
class ByteWriter;
}  // namespace ltlo::map

namespace ltlo::tracking {

enum class TrackingState;  // tracker.h
struct TrackingStats;      // tracker.h

/// The Tracker's state the loss policy reads and sets for one frame: references into the Tracker
/// (read where the policy reads them, so a step that changes them is seen), and this frame's values.
struct LossContext {
  map::Atlas& atlas;
  TrackingState& state;
  TrackingStats& stats;
  bool& frame_tracked;
  const map::KeyFrameId& reference_kf;
  const map::KeyFrameId& last_kf;
  const std::shared_ptr<map::KeyFrame>& last_kf_ptr;
  /// IMU since the last keyframe and whether it was re-anchored while lost (the rejoin's link).
  const std::shared_ptr<imu::Preintegrated>& imu_since_keyframe;
  const bool& imu_chain_broken;
  bool was_lost = false;         ///< the previous frame was lost
  int min_inliers = 0;           ///< Tracker::minInliers() of this frame
  bool has_vocabulary = false;   ///< relocalisation possible
  bool imu_predicted = false;    ///< the IMU predicted this frame's state
  bool imu_link = false;         ///< ... with the inertial link (and the prediction's information)
  SE3 T_w_b_imu = SE3();         ///< the IMU's prediction (with imu_predicted)
  double last_tracked_t_s = 0.0;
  /// Before the IMU is initialised (Tracking.StartReacquireSpeed): the position standard deviation
  /// of the lost frame's prediction (its rotation the gyroscope's) for the guided re-acquisition;
  /// infinity: none.
  double start_reacquire_sigma_m = std::numeric_limits<double>::infinity();
  /// Before the IMU is initialised (Tracking.GyroRotationGate): the frame's rotation R_w_b as the
  /// gyroscope carries it from the previous frame's; a tracked or recovered pose whose rotation is
  /// further from it than gyro_gate_rad makes the frame lost. Lost frames are held at the
  /// gyroscope's rotation too, so the chain reaches back to the last tracked frame; while poses keep
  /// disagreeing, the loss policy starts a new map in the gyroscope's orientation. Absent: no gate.
  std::optional<Mat3> gyro_R_w_b = std::nullopt;
  double gyro_gate_rad = 0.0;
};

/// The Tracker's steps the loss policy runs: the searches of a lost frame (tracker_reacquire.cc)
/// and the map changes it decides (tracker.cc, tracker_keyframe.cc).
class RecoverySteps {
 public:
  /// Guided re-acquisition of the active map at the IMU prediction T_w_b_pred, in windows of
  /// sigma_position_m (Tracking.Reacquire); pose inliers (0 when not re-acquired).
  virtual int reacquire(map::Frame& frame, const SE3& T_w_b_pred, double sigma_position_m) = 0;
  /// Relocalisation in the active map; pose inliers (0 when not relocalised).
  virtual int relocalise(map::Frame& frame) = 0;
  /// The lost frame gets the predicted state (T_w_b_pred, v_w_b_pred: the motion model's).
  virtual void holdPrediction(map::Frame& frame, const SE3& T_w_b_pred, const Vec3& v_w_b_pred) = 0;
  /// A keyframe of the frame at its predicted pose extends the active map: every static keypoint
  /// with depth becomes a map point; the IMU chain continues.
  virtual void extendMapAtPrediction(map::Frame& frame) = 0;
  /// The tracker starts over in the new active map at the frame's predicted pose.
  virtual void initialiseNewMap(map::Frame& frame) = 0;
  /// Bookkeeping of a frame that leaves track() with a pose (tracked or predicted).
  virtual void recordFramePose(const map::Frame& frame) = 0;

 protected:
  ~RecoverySteps() = default;
};

/// What the loss policy made of the frame.
enum class Recovery {
  kTracked,      ///< the motion model tracked it
  kReacquired,   ///< the guided re-acquisition found the active map
  kRelocalised,  ///< BoW relocalisation
  kLost,         ///< not tracked: the predicted state
  kMapExtended,  ///< not tracked: a keyframe at the IMU-predicted pose extends the active map
  kNewMap,       ///< not tracked: a new map starts at the predicted pose
};

struct LossDecision {
  Recovery recovery = Recovery::kTracked;
  int inliers = 0;  ///< pose inliers of the frame (after the recovery searches)
  /// The frame goes on as tracked (matches to keep, keyframe decision); else track() is done.
  bool tracked() const {
    return recovery == Recovery::kTracked || recovery == Recovery::kReacquired || recovery == Recovery::kRelocalised;
  }
};

class LossRecovery {
 public:
  explicit LossRecovery(const TrackerOptions& options) : options_(options) {}

  /// After the motion model (`inliers` its pose inliers): re-acquire -> relocalise -> the lost
  /// frame's state, a map extension or a new map. Sets stats.inliers, the frame's reference
  /// keyframe and, for an untracked frame, state and frame_tracked.
  LossDecision recover(map::Frame& frame, int inliers, const LossContext& context, RecoverySteps& steps,
                       const SE3& T_w_b_pred, const Vec3& v_w_b_pred);

  /// A tracked frame: an open IMU-carried stretch closes when it matches at least min_inliers
  /// points from before it; else the stretch's fix is renewed (see the members).
  void onTrackedFrame(const map::Frame& frame, int min_inliers);

  /// The position sigma compared with Tracking.MaxImuPositionSigma for a frame at t_s predicted by
  /// the IMU with its link: sigma_p of the prediction's information, sigma_a the world
  /// acceleration's error, bias_drift_m its drift since the last tracked frame, lever_m the
  /// rotation's through T_b_c (tracker_inertial.cc).
  void updateCarriedSigma(double t_s, double sigma_p, double sigma_a, double bias_drift_m, double lever_m);
  double carriedPositionSigma_m() const { return carried_position_sigma_m_; }

  /// The least velocity sigma (m/s) a frame at t_s may hand on to a new map (its origin and its
  /// first keyframe's velocity prior): while the active map, started by the loss policy, has not yet
  /// tracked Tracking.NewMapVelocityTrust in a row, the sigma it started with widened by
  /// sigma_a_m_s2 per second since; 0 otherwise (the carried marginal alone).
  double velocitySigmaFloor_m_s(double t_s, double sigma_a_m_s2) const;

  /// Maps started by the loss policy (the first map is not counted).
  int mapsCreated() const { return maps_created_; }

  /// The policy's state between two frames (the IMU-carried stretch and the last tracked run; the
  /// count of maps is a statistic and not part of it), for a run resumed from an atlas file
  /// (Tracker::writeState).
  void writeState(map::ByteWriter& out) const;
  void readState(map::ByteReader& in);

 private:
  /// Lost frame: the predicted state, then a new map or a keyframe at the prediction when due.
  LossDecision handleLostFrame(map::Frame& frame, const LossContext& context, RecoverySteps& steps,
                               const SE3& T_w_b_pred, const Vec3& v_w_b_pred);
  /// Keyframe at the prediction: the stretch opens (or goes on) with its points.
  void extendMap(map::Frame& frame, const LossContext& context, RecoverySteps& steps, double lost_for_s,
                 double sigma_m);
  /// New map at the predicted pose, with its origin in the parent's world when the IMU placed it.
  void startNewMap(map::Frame& frame, const LossContext& context, RecoverySteps& steps, double lost_for_s,
                   double sigma_m, bool keyframe_in_map);

  TrackerOptions options_;
  int maps_created_ = 0;
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
  /// A map started at the IMU's prediction whose velocity is not yet trusted (velocitySigmaFloor_m_s):
  /// the velocity sigma it started with (0: none, or trusted) and its start time.
  double untrusted_velocity_sigma_m_s_ = 0.0;
  double untrusted_velocity_t_s_ = 0.0;
};

}  // namespace ltlo::tracking
