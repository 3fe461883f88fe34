#pragma once
/// TrackingOptions (Tracking.*, RGBD.VirtualBaseline): the tracking stage's typed settings, part of
/// `Settings` (settings.h, which includes this header; the same conventions: every field carries its
/// DESIGN.md default and a `///` comment naming meaning, unit, YAML key and accepted range).
/// Kept apart from settings.h only for size.

namespace ltlo {

class SettingsFile;

/// Tracking: the inertial pose optimisation and the loss policy (Tracking.*), and the depth model
/// of every RGB-D reprojection edge (RGBD.VirtualBaseline).
struct TrackingOptions {
  /// After IMU initialisation, optimise each frame's pose, velocity and biases with the static
  /// reprojection edges and the preintegration link to the last keyframe or the last frame, whose
  /// marginal enters as a prior (Tracking.InertialPoseOptimisation, 0/1). 0: the IMU only predicts
  /// the pose and seeds the search (an ablation).
  bool inertial_pose_optimisation = true;
  /// With the IMU's prediction, tracking starts from it, not from the dense alignment's refinement
  /// of it (0; the alignment still gives the segmentation): the pose optimisation already weighs
  /// the prediction against the features, and on static runs starting from the refinement cost
  /// ~10 % of ATE. 1: start from the refinement (Tracking.DenseStateWithImu, 0/1)
  bool dense_state_with_imu = false;
  /// pose inliers a frame needs to be tracked by vision alone (no IMU, or before its
  /// initialisation) (Tracking.MinInliers, [6, 10000])
  int min_inliers = 30;
  /// pose inliers a frame needs to be tracked with the inertial optimisation: its IMU prior
  /// already fixes the pose to ~mm over a frame, the inliers only have to correct it
  /// (Tracking.MinInliersImu, [3, 10000], at most Tracking.MinInliers)
  int min_inliers_imu = 10;
  /// With the inertial optimisation, an untracked frame keeps the IMU prediction; while its
  /// position standard deviation (largest axis, m) stays below this, a frame whose static
  /// keypoints do not match the map extends the map at the predicted pose instead of starting a
  /// new map (Tracking.MaxImuPositionSigma, [0.001, 10])
  double max_imu_position_sigma_m = 0.05;
  /// Least standard deviation of the world acceleration the IMU prediction integrates (bias and
  /// gravity, held fixed at each keyframe link and so left out of the tracker's covariance), m/s^2;
  /// the (re)initialisation's own posterior sigma is used when larger. An IMU-only stretch of t
  /// seconds adds 0.5 sigma t^2 to the predicted position's standard deviation (search windows;
  /// for Tracking.MaxImuPositionSigma t runs from the last visual fix: the last anchored frame, or
  /// a keyframe placed at the prediction whose points tracking then held for 0.5 s, whose own sigma
  /// adds in quadrature) (Tracking.AccBiasSigma, [0, 10])
  double acc_bias_sigma_m_s2 = 0.03;
  /// Lost for at least this long (s, since the last tracked frame): a frame with enough static
  /// keypoints starts a new map (or, see Tracking.MaxImuPositionSigma, extends the map); a
  /// negative value never does (Tracking.NewMapAfter, [-1, 1000])
  double new_map_after_s = 1.0;
  /// Static keypoints with depth a lost frame needs to extend the map at the IMU-predicted pose
  /// (Tracking.MaxImuPositionSigma); fewer than a new map needs (100): the IMU fixes the pose, the
  /// points only have to be tracked by the next frames, and under a large occluder the static
  /// part of the view holds few keypoints (Tracking.MinExtendFeatures, [10, 10000])
  int min_extend_features = 40;
  /// While lost, the IMU preintegration from the last keyframe is kept at most this long (s);
  /// beyond, it is re-anchored on the predicted state and the next keyframe starts a new IMU chain
  /// (Tracking.MaxLostImuInterval, [0.1, 1000])
  double max_lost_imu_interval_s = 5.0;
  /// Trajectory output of IMU-carried stretches (frames posed by the IMU alone while vision
  /// could not track): once vision anchors the frame after the stretch, the difference between its
  /// dead-reckoned and its anchored pose is spread over the stretch in the IMU error model's shape
  /// (system/carried_stretch.h; live tracking and the map are unchanged)
  /// (Tracking.SmoothCarriedFrames, 0/1). 0: the stretch keeps the dead reckoning (an ablation).
  bool smooth_carried_frames = true;
  /// Standard deviation of the velocity of the last tracked frame before a carried stretch, m/s:
  /// with Tracking.AccBiasSigma it sets how the end correction is split between a velocity error
  /// (growing linearly) and an acceleration error (quadratically) (Tracking.CarriedVelocitySigma,
  /// [0, 10]; 0.01: a frame tracked at 30 Hz with mm-level pose noise)
  double carried_velocity_sigma_m_s = 0.01;
  /// Inertial bridge of IMU-carried stretches in the trajectory output (system/carried_bridge.h;
  /// with Tracking.SmoothCarriedFrames): once the frame after a stretch is anchored, the stretch's
  /// poses and velocities are solved again from the frames' own IMU preintegration between the
  /// last tracked frame (held, velocity prior Tracking.CarriedVelocitySigma) and the anchored one
  /// (held), with one gyroscope and accelerometer bias over it (priors Tracking.CarriedGyroBiasSigma
  /// and Tracking.AccBiasSigma about the last tracked frame's); an accelerometer bias error then
  /// turns with the robot, as it does in the dead reckoning. Where the IMU data is incomplete the
  /// blend (Tracking.CarriedVelocitySigma's share) is used. Only the output changes; the IMU data
  /// of carried frames and their margins is kept for it (Tracking.CarriedBridge, 0/1; 0: the blend
  /// alone; off by default: not better than the blend on the simulator's realsense profile,
  /// docs/results.md "Inertial bridge").
  bool carried_bridge = false;
  /// Tracked frames within this time before and after a carried stretch enter its inertial bridge
  /// with a prior on their final poses (3 mm, 0.2 deg): they tell the velocities at both ends and
  /// the biases (Tracking.CarriedBridgeMargin, s, [0, 5]; 0: the two end frames only)
  double carried_bridge_margin_s = 0.5;
  /// Standard deviation of the gyroscope bias over a carried stretch about the last tracked
  /// frame's estimate, rad/s (the random walk over the stretch is added): the anchored end's
  /// rotation tells the rest (Tracking.CarriedGyroBiasSigma, (0, 1])
  double carried_gyro_bias_sigma_rad_s = 0.002;
  /// Guided re-acquisition of the active map by a lost frame with the IMU prediction
  /// (Tracking.Reacquire, 0/1): the map points of the keyframes around the predicted pose are
  /// projected with it, matched to the frame's static keypoints with depth in windows of
  /// Tracking.ReacquireGateSigmas standard deviations of the predicted reprojection, and a 3-D-3-D
  /// RANSAC pose is accepted only within that many sigmas of the prediction, then refined against
  /// the local map. Tried before the BoW relocalisation and before a new map is started.
  bool reacquire = true;
  /// Gate of a re-acquired pose and half width of its search windows, in standard deviations of
  /// the IMU-carried prediction (Tracking.ReacquireGateSigmas, [1, 20])
  double reacquire_gate_sigmas = 3.0;
  /// Least rotation gate of a re-acquired pose, degrees: the gyroscope bias error is held fixed
  /// at the links and so is missing from the predicted rotation sigma
  /// (Tracking.ReacquireMinRotationGate, [0, 180])
  double reacquire_min_rotation_gate_deg = 3.0;
  /// Largest search half window of the re-acquisition, px at level 0
  /// (Tracking.ReacquireMaxRadius, [5, 2000])
  double reacquire_max_radius_px = 160.0;
  /// Pose inliers a re-acquired frame needs after the local-map search
  /// (Tracking.ReacquireMinInliers, [6, 10000])
  int reacquire_min_inliers = 25;
  /// Virtual stereo baseline of the RGB-D edges, m: bf = fx * b, so a keypoint with depth d and
  /// standard deviation sigma (px) has a depth standard deviation sigma d^2 / (fx b), that of a
  /// stereo rig of baseline b with the same disparity error. For a sensor with depth noise
  /// sigma_d = k d^2 at 1 px: b = 1 / (fx k); reading the depth at the rounded keypoint pixel on a
  /// surface slanted by theta adds b_slope = 1 / tan(theta), 1/b^2 = 1/b_sensor^2 + 1/b_slope^2
  /// (RGBD.VirtualBaseline, [0.001, 100]; 0.5 for a Kinect-class sensor: config_yaml/*.yaml)
  double virtual_baseline_m = 0.5;
  /// A run in a loaded atlas (--load-atlas) starts lost in it: each frame is relocalised in the
  /// loaded maps (BoW + guided search) until one is; not relocalised this long after the first
  /// frame, a new map starts there, which the loop closer merges into the loaded one when it
  /// recognises it (Tracking.LoadedAtlasNewMapAfter, s, [-1, 1000]; -1: never, keep trying; 0: a new
  /// map at once, joined to the loaded ones by the loop closer only)
  double loaded_atlas_new_map_after_s = 10.0;
  /// Localisation only (--localisation-only, with a loaded atlas): no keyframes, no map points, no
  /// new map; every frame is tracked against the loaded maps, relocalised or re-acquired there
  /// when lost, the IMU carrying the pose in between (Tracking.LocalisationOnly, 0/1)
  bool localisation_only = false;
  /// Standstill (issue 32). Zero-velocity update (Tracking.Zupt, 0/1): while the IMU's
  /// zero-velocity test (Tracking.ZuptWindow, Tracking.ZuptThreshold) says the robot is at rest, each
  /// frame keeps the pose of the first still frame, zero velocity and the biases it had (it is still
  /// matched, for the record and the next frame); a view full of moving boxes then cannot move it,
  /// and frames the boxes leave without static matches are not lost. 0: frames are tracked as usual
  bool zupt = false;
  /// No keyframe while the IMU says the robot is at rest (Tracking.ZuptNoKeyFrames, 0/1): boxes
  /// moving through the view lower the overlap and would make one keyframe after another of the
  /// same place
  bool zupt_no_keyframes = false;
  /// Samples the zero-velocity test looks at, s (Tracking.ZuptWindow, [0.1, 5])
  double zupt_window_s = 0.3;
  /// Largest mean squared gyro reading (minus the bias) and accelerometer deviation from its window
  /// mean that count as rest, in units of the white noise variance of one reading at the
  /// calibration's density (IMU.NoiseGyro / IMU.NoiseAcc squared times IMU.Frequency; 1 at rest)
  /// (Tracking.ZuptThreshold, [1, 100])
  double zupt_threshold = 3.0;
  /// Confirm rest with the static part of the view (Tracking.ZuptVisualCheck, 0/1): a frame whose
  /// matched static keypoints (at least 10) reproject at the held pose with a median error above
  /// Tracking.ZuptMaxDisplacement is tracked as usual (the IMU alone cannot tell a slow constant
  /// motion from rest)
  bool zupt_visual_check = false;
  /// Median reprojection error of the static matches at the held pose that still confirms rest, px
  /// (Tracking.ZuptMaxDisplacement, [0.1, 100])
  double zupt_max_displacement_px = 2.0;
  /// Occluded start (issue 32). The first keyframe of a run's first map is made before any motion
  /// was seen, so its points may lie on a mover that covers the view from the first frame. For this
  /// long after it, s, they are provisional: every later frame projects them with its pose and a
  /// point that lands, with its depth matching the frame's, on clusters the segmentation (with the
  /// gyroscope's or the IMU's motion prior) calls dynamic in Tracking.StartDynamicVotes frames more
  /// than on static ones is erased, so that neither tracking nor a recovery can take the mover as
  /// the world (Tracking.StartProvisional, [0, 1000]; 0: the first keyframe's points are final)
  double start_provisional_s = 0.0;
  /// Frames a provisional point must be seen on dynamic clusters, beyond those it was seen on
  /// static ones, to be erased (Tracking.StartDynamicVotes, [1, 100])
  int start_dynamic_votes = 3;
  /// Before the IMU is initialised, a lost frame re-acquires the map by the guided search
  /// (Tracking.Reacquire) around its prediction, whose rotation is the gyroscope's, in windows of a
  /// position standard deviation of 0.05 m plus this speed times the time since the last tracked
  /// frame: the velocity is unknown, and the tracking lost under an occluded start lags behind by
  /// about the robot's speed (Tracking.StartReacquireSpeed, m/s, [0, 10]; 0: no re-acquisition
  /// before the IMU is initialised, and lost frames keep the constant-velocity rotation)
  double start_reacquire_speed_m_s = 0.0;
  /// Within Tracking.StartProvisional of the first keyframe and before the IMU is initialised, a
  /// frame recovered by relocalisation or re-acquisition cuts the keyframes' IMU chain there: the
  /// keyframes before it were posed while a mover moving with the camera may have held the view,
  /// and the IMU initialisation (which uses the chain ending at the newest keyframe) starts after
  /// them (Tracking.StartRecoveryCutsImu, 0/1)
  bool start_recovery_cuts_imu = false;
  /// With the same condition, a frame relocalised (not re-acquired) on another keyframe than the
  /// map's gauge makes that keyframe the gauge, and the keyframes made before the frame leave the
  /// map: the frame landed in that keyframe's world, which differs from the first keyframe's when
  /// the keyframe was made while tracking followed a mover (Tracking.StartRecoveryGauge, 0/1)
  bool start_recovery_gauge = false;
  /// Within the same window, before the IMU is initialised: the pose-gravity check's bound, above which
  /// the frame recovers as a relocalised one (tracker_start.cc) (Tracking.StartMotionCheck, m/s^2, [0, 100]; 0: off)
  double start_motion_check_m_s2 = 0.0;
  /// Before any map's IMU initialisation, the largest turn of a pose from the gyroscope's rotation before the
  /// frame is made lost (loss_recovery.cc) (Tracking.GyroRotationGate, deg, [0, 180]; 0: off)
  double gyro_rotation_gate_deg = 0.0;
  /// Before the IMU is initialised, frames lost with the gyroscope's prediction
  /// (Tracking.StartReacquireSpeed) form a carried stretch of the final trajectory like the IMU's
  /// (system/carried_stretch.h): once a frame is tracked again, its difference to the prediction is
  /// spread over them (Tracking.StartCarriedLost, 0/1; the online poses are unchanged)
  bool start_carried_lost = false;
  /// While the view is too poor to start the run's first map, the IMU alone keeps each frame's pose
  /// (tracking/imu_dead_reckoning.h): the orientation from the gyroscope, the pose held and gravity
  /// and the gyro bias taken from the accelerometer and gyro at rest, the position integrated once
  /// gravity is known; the map then starts at the dead-reckoned pose (Tracking.PreMapImuPose, 0/1;
  /// 0: those frames have no pose)
  bool pre_map_imu_pose = false;
  /// A new map started after a loss the IMU carried (IMU initialised) keeps the dead-reckoned
  /// velocity of its first keyframe under a prior, the velocity marginal of the carried
  /// prediction's information, until a frame is linked to a later keyframe; without it that
  /// velocity is left free and the first frame's pose alone (against few new map points) fixes it,
  /// and a wrong one becomes the motion prior of the next frames' dense segmentation
  /// (Tracking.NewMapVelocityPrior, 0/1)
  bool new_map_velocity_prior = false;
  /// A map started after a loss hands on its velocity with its own marginal (to the next new map's
  /// velocity prior and origin, Tracking.NewMapVelocityPrior and LocalMapping.GaugeVelocityPrior)
  /// only once its frames have tracked this long in a row: before, a few frames against a new map
  /// that may hold an occluder's points are not evidence of the world's velocity, and the velocity
  /// sigma handed on is at least the one the map started with, widened by the acceleration error
  /// since (loss_recovery.h; issue 32, ltlo seed 5: a 0.1-0.3 s map handed on 0.03 m/s for a velocity
  /// 0.38 m/s off). Seconds; 0: every map's marginal is trusted (Tracking.NewMapVelocityTrust)
  double new_map_velocity_trust_s = 1.0;

  static TrackingOptions load(const SettingsFile& file);
};

}  // namespace ltlo
