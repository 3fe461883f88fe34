#pragma once
/// TrackerOptions: the settings of the Tracker (tracker.h) and of its loss policy
/// (loss_recovery.h), and the guided search of the re-acquisition they give.
#include "ltlo/core/settings.h"
#include "ltlo/imu/zero_velocity_detector.h"
#include "ltlo/place/guided_place_match.h"
#include "ltlo/tracking/relocaliser.h"

namespace ltlo::tracking {

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

  // ---- a run in a loaded atlas ----
  /// The atlas holds the maps of an earlier run (System's --load-atlas): the first frames are
  /// relocalised in them instead of starting a map, for up to tracking.loaded_atlas_new_map_after_s
  /// (tracker_loaded_start.cc). With tracking.localisation_only nothing is ever added to the atlas.
  bool start_in_loaded_atlas = false;
  /// The IMU (re)initialisation's settings (core settings, ImuInit.*): with
  /// tracking.localisation_only no keyframes are made for local mapping to estimate the biases on,
  /// so the tracker estimates them itself over the frames the map localised (iterations, bias priors).
  ImuInitOptions imu_init;
  // ---- standstill (issue 32; tracker_standstill.cc) ----
  /// Run the IMU's zero-velocity test on every frame (System: with the IMU, when Tracking.Zupt,
  /// Tracking.ZuptNoKeyFrames or ImuInit.FromRest is on); tracking.zupt* say what rest changes.
  bool zero_velocity_test = false;
  /// The test's window, threshold and the calibration's noise densities and rate.
  imu::ZeroVelocityOptions zero_velocity;
  /// Before the IMU initialisation, a keyframe at rest once the test has held for rest_time_s since
  /// the last keyframe (ImuInit.FromRest, ImuInit.RestTime): local mapping initialises from it.
  bool rest_keyframe = false;
  double rest_time_s = 2.0;
};

/// The guided search of the re-acquisition (Tracking.Reacquire*, the local-map window floor and
/// keyframes, the descriptor and RANSAC thresholds), without its sigmas and seed; the loop
/// closer's rejoin (Loop.Rejoin) searches with the same settings.
place::GuidedPlaceMatchOptions reacquireSearchOptions(const TrackerOptions& options);

}  // namespace ltlo::tracking
