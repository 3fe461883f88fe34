#pragma once
/// Typed algorithm settings (STYLE.md section 4): one settings file becomes one `Settings` of typed
/// per-module option structs, loaded once by `system` or an Example, validated, logged in full and
/// then passed on by const&. Modules never open files themselves.
///
/// Every field below carries its DESIGN.md default and a `///` comment naming meaning, unit, YAML
/// key and accepted range. All algorithm keys are required in a config file (config_yaml/*.yaml
/// list every one with a comment); only the Sequence.* keys are optional. A missing, mistyped or
/// out-of-range key throws ConfigError naming file, key, expected range and value found:
///   "config_yaml/tum_rgbd.yaml: Seg.Clusters = 1, expected an integer in [2, 256]"
/// An unknown key (usually a typo) is logged as a warning and listed in Settings::unknown_keys. A
/// retired key (one the settings no longer read, e.g. Seg.LambdaD) still found in a file is
/// logged with one line saying it is no longer used and what replaced it; it is not an unknown key.
#include <string>
#include <vector>

#include "ltlo/core/calib.h"
#include "ltlo/core/sequence_options.h"
#include "ltlo/core/tracking_options.h"

namespace ltlo {

class SettingsFile;

/// ORB feature extraction on the intensity image (ORB-SLAM-style pyramid and FAST thresholds).
struct OrbOptions {
  /// features per image (ORBextractor.nFeatures, [50, 20000])
  int num_features = 1000;
  /// scale ratio between pyramid levels (ORBextractor.scaleFactor, [1.05, 2])
  double scale_factor = 1.2;
  /// pyramid levels (ORBextractor.nLevels, [1, 16])
  int num_levels = 8;
  /// FAST threshold, grey levels 0-255 (ORBextractor.iniThFAST, [1, 255])
  int ini_th_fast = 20;
  /// FAST threshold for cells where iniThFAST finds nothing, grey levels (ORBextractor.minThFAST,
  /// [1, iniThFAST])
  int min_th_fast = 7;

  static OrbOptions load(const SettingsFile& file);  ///< reads and validates; throws ConfigError
};

/// Depth over-segmentation and the dense/sparse static-segmentation terms (thesis Eq. 50-64).
struct SegmentationOptions {
  /// Segment every frame (Seg.Enable, 0/1). 0: every frame is one static cluster, the static core's
  /// behaviour (an ablation: boxes are then mapped and tracked as static).
  bool enable = true;
  /// Estimate the initial segmentation and state densely, thesis Eq. 59-64 (Seg.DenseInit, 0/1).
  /// 0: depth clusters with every gamma = 1 (local mapping may still refine them; an ablation).
  bool dense_init = true;
  /// K of the depth K-means (Seg.Clusters, [2, 255]; labels are 8-bit with label K = no depth)
  int num_clusters = 24;
  /// K-means iterations from the grid seeds (Seg.KMeansIterations, [1, 50])
  int kmeans_iterations = 3;
  /// touching clusters closer than this in 3-D are connected in the graph V_i, m
  /// (Seg.MaxNeighbourGap, [0.001, 10])
  double max_neighbour_gap_m = 0.15;
  /// alpha_I, intensity-to-depth residual scale, Eq. 60 (Seg.AlphaIntensity, [0.001, 10])
  double alpha_intensity = 0.15;
  /// lambda_I in w_I = 1 / (lambda_I sigma_I^2 + |grad I|), Eq. 64
  /// (Seg.NoiseWeightIntensity, [0, 1e6])
  double noise_weight_intensity = 10.0;
  /// lambda_D in w_D = 1 / (lambda_D sigma_D^2 + |grad D|), Eq. 64 (Seg.NoiseWeightDepth, [0, 1e6])
  double noise_weight_depth = 10.0;
  /// sigma_I, intensity noise, intensity in [0, 1] (Seg.SigmaIntensity, [1e-6, 1])
  double sigma_intensity = 0.02;
  /// sigma_D, depth noise at 1 m, m; Eq. 64 uses sigma_D(z) = sigma_D (z / 1 m)^2
  /// (Seg.SigmaDepth, [1e-6, 1])
  double sigma_depth_m = 0.01;
  /// c, inflection point of the Cauchy penalty F, in weighted residual units
  /// (Seg.CauchyC, [1e-6, 1000])
  double cauchy_c = 0.5;
  /// lambda_s, weight of R_s (beta prior), Eq. 55, in units of the Huber cost of whitened
  /// reprojection errors: with its clusters voting static, a point is half dynamic when its window
  /// observations cost lambda_s (Seg.LambdaS, [0, 1e6])
  double lambda_s = 100.0;
  /// lambda_p, 1/m: gamma~ = 1 - mean over the map points projecting into the cluster of
  /// min(1, lambda_p beta (point depth - image depth)^+), Eq. 56 (Seg.LambdaP, [0, 1000])
  double lambda_p = 2.0;
  /// lambda_phi in beta~ = phi(lambda_phi, mean gamma), Eq. 57 (Seg.LambdaPhi, [0, 0.99])
  double lambda_phi = 0.5;
  /// clusters with gamma above this give tracking features and new map points (Seg.StaticThreshold,
  /// [0, 1])
  double static_threshold = 0.5;
  /// Estimate a per-frame affine brightness change (gain and offset, auto-exposure) inside the
  /// dense initial state and segmentation: the intensity residual of Eq. 61 becomes
  /// I_{i-1}(W(u, T)) - (a I_i(u) + b) (Seg.AffineBrightness, 0/1). 0: Eq. 61 as it stands, an
  /// exposure step then reads as motion or as dynamic clusters.
  bool affine_brightness = true;
  /// weight of the brightness change's prior towards gain 1, offset 0, as a share of the fit's own
  /// weight. The fit measures the mean grey always and the gain from the spread of the image's
  /// 8 x 8 block means: the prior shrinks a gain step by about prior / (prior + var), so at 1e-5 it
  /// matters only below a spread (std) of about one 8-bit level (a texture-poor frame, whose gain
  /// then stays near 1 and its change goes to the offset) (Seg.AffineBrightnessPrior, [0, 100])
  double affine_brightness_prior = 1e-5;
  /// Write segmentation_final/ after the run: every frame's mask relabelled against the final static
  /// map and poses (system/hindsight_masks.h; Seg.HindsightMasks, 0/1). 0: segmentation/ only.
  bool hindsight_masks = true;
  /// Static map points that must vote in a cluster before it may turn dynamic in hindsight
  /// (Seg.HindsightMinPoints, [1, 1000])
  int hindsight_min_points = 3;
  /// A point behind a frame's surface votes only when the ray of a keyframe that saw it passes within
  /// this distance of that surface point, m (Seg.HindsightRayTolerance, [0.001, 1])
  double hindsight_ray_tolerance_m = 0.05;
  /// A region judged dynamic in hindsight turns dynamic where its nearest voter votes dynamic and lies
  /// within this distance, m (Seg.HindsightVoteRadius, [0.01, 10])
  double hindsight_vote_radius_m = 0.3;
  /// Hindsight also turns dynamic regions static where the static points vote so (Seg.HindsightToStatic, 0/1)
  bool hindsight_to_static = true;
  /// ... when at least this share of their votes (beta-weighted) lie on the surface, none behind
  /// (Seg.HindsightStaticShare, [0.5, 1])
  double hindsight_static_share = 0.9;
  /// Hindsight masks also ask the keyframes' depth images: a surface point of a frame that keyframes saw
  /// through (the room seen empty there) is dynamic (Seg.HindsightFreeSpace, 0/1)
  bool hindsight_free_space = true;
  /// Keyframes that must see through a surface point (Seg.HindsightFreeSpaceViews, [1, 20])
  int hindsight_free_space_views = 2;
  /// Keyframes a frame asks at most, those that saw most of its surface (Seg.HindsightFreeSpaceMaxViews,
  /// 0 = all): bounds the pass's cost per frame on long runs, whose revisits add views of the same walls
  int hindsight_free_space_max_views = 32;
  /// Frames between the keyframes also serve as free-space views, one per this many seconds of the run
  /// (Seg.HindsightFreeSpaceFrameInterval, [0, 60]; 0: the keyframes only): a door that swings open shows
  /// where its closed leaf stood to the frames of that moment, which need not include a keyframe
  double hindsight_free_space_frame_interval_s = 0.0;
  /// Hindsight masks judge a frame's clusters again with the Gamma step of Eq. 59-61 at the final
  /// relative poses of its previous and reference frames when the online motion over the reference
  /// baseline moved the frame's surface by more than Seg.HindsightRejudgeMinShift label pixels from
  /// where the final poses put it (Seg.HindsightRejudge, 0/1): a stretch dead-reckoned on a biased
  /// IMU called the static room beside a mover dynamic
  bool hindsight_rejudge = true;
  /// Mean image shift of the frame's surface, label pixels, between the online and the final motion
  /// over the reference baseline above which the frame is judged again (Seg.HindsightRejudgeMinShift,
  /// [0, 100])
  double hindsight_rejudge_min_shift_px = 0.5;
  /// A keyframe saw through a frame's surface point in hindsight when its depth there lies beyond the
  /// point by more than this + 3 sigma of the sensor's depth noise (Recon.DepthNoise z^2), at most the
  /// V_i gap (Seg.HindsightFreeSpaceTolerance, m, [0, 1]; 0: the V_i gap); the noise measured in the
  /// run's depth images instead when larger. The gap (0.15 m from 1.6 m on) took a closed door leaf 6 cm
  /// in front of its wall for the wall
  double hindsight_free_space_tolerance_m = 0.02;

  static SegmentationOptions load(const SettingsFile& file);
};

/// Keyframe decision in tracking.
struct KeyFrameOptions {
  /// new keyframe when the overlap (fraction of the last keyframe's tracked static points still
  /// seen) drops below (KF.MaxOverlap, [0.05, 0.99])
  double max_overlap = 0.75;
  /// tracking is weak (new keyframe) below this many tracked static map points
  /// (KF.MinTrackedPoints, [0, 10000])
  int min_tracked_points = 50;
  /// a keyframe made only because tracking is weak needs at least this long since the last
  /// keyframe, s (KF.WeakMinInterval, [0, 10]). Beside a large occluder the static view can hold
  /// fewer features than KF.MinTrackedPoints however many keyframes are made: one keyframe per
  /// frame then adds single-view points of the same strip and aborts every local BA, so the window
  /// spans a fraction of a second and drifts. 0: a weak frame is always a keyframe (ablation).
  double weak_min_interval_s = 0.1;
  /// a keyframe at least this often, s; bounds IMU preintegration time (KF.MaxInterval, [0.01,
  /// 100])
  double max_interval_s = 1.0;
  /// pose inliers a frame needs to become a keyframe when vision alone tracked it
  /// (KF.MinInliers, [3, 10000]): it must be anchored in the map by points, local and global BA
  /// would otherwise hold it by a handful
  int min_inliers = 16;
  /// pose inliers a frame tracked with the inertial optimisation needs to become a keyframe when
  /// tracking has just resumed after a loss (no keyframe since) (KF.MinInliersInertial, [3,
  /// 10000]): its IMU link anchors it too, so after an occlusion or a black-out a view that is
  /// mostly unmapped extends the map as soon as it is tracked, instead of being lost again for want
  /// of points (KF.MinInliers restores the vision-only rule)
  int min_inliers_inertial = 10;
  /// Revisits (issue 32): a frame whose view the map already holds, i.e. at least
  /// KF.RevisitMappedShare of its pose inliers are points seen by KF.RevisitMinObservers keyframes
  /// or more (the redundancy test of keyframe culling, ORB-SLAM's 90 % seen by >= 3 others, applied
  /// before the keyframe is made) and at most KF.RevisitMaxNewShare of its static features with
  /// depth would become new points, makes no keyframe on the overlap, weak-tracking or interval rule
  /// until this long has passed since the last keyframe, s (KF.RevisitMaxInterval, [0, 100]; it
  /// bounds the IMU preintegration between keyframes as KF.MaxInterval does elsewhere). 0: off,
  /// every trigger makes its keyframe (the rule of the first visit everywhere).
  double revisit_max_interval_s = 0.0;
  /// share of the pose inliers that must be established points for the view to count as mapped
  /// (KF.RevisitMappedShare, [0.5, 1])
  double revisit_mapped_share = 0.9;
  /// keyframes an established point is seen by (KF.RevisitMinObservers, [2, 100])
  int revisit_min_observers = 3;
  /// largest share of the frame's static keypoints with depth that match no map point and would
  /// become new points, for the view to count as mapped (KF.RevisitMaxNewShare, [0, 1]; 1: any)
  double revisit_max_new_share = 1.0;

  static KeyFrameOptions load(const SettingsFile& file);
};

/// Robust visual-inertial BA over a sliding window (thesis Eq. 50-58) and map maintenance.
struct LocalMappingOptions {
  /// keyframes optimised (their covisible neighbours held fixed) (LocalMapping.WindowSize, [2,
  /// 100])
  int window_size = 10;
  /// At most this many other keyframes observing the window's points are held fixed in it, those
  /// sharing most points first (LocalMapping.MaxFixedKeyFrames, [1, 1000]). A room revisited lap
  /// after lap gives every point more observers, and the fixed set (its observations) grows to this
  /// cap: it sets how the local BA's cost grows over a long run
  int max_fixed_keyframes = 50;
  /// At most this many observations of a window point from fixed keyframes enter local BA, those
  /// of the fixed keyframes sharing most points with the window first (LocalMapping.
  /// MaxFixedObservationsPerPoint, [0, 1000]; 0: all). A point seen from every lap of a revisited
  /// room is held by a few fixed views as well as by all: the rest only add cost (issue 32)
  int max_fixed_observations_per_point = 0;
  /// Observations of local BA's points from fixed keyframes at most this many times those from the
  /// optimised keyframes (LocalMapping.MaxFixedObservationRatio, [0, 1000]; 0: no limit). Above it,
  /// the per-point limit above is lowered to the largest that fits. A young map's windows stay whole;
  /// a revisited room's stop growing with every lap, so the mapping cost per keyframe is bounded on
  /// long runs (issue 32). A ratio, not a count: the same value holds at any image size
  double max_fixed_observation_ratio = 0.0;
  /// Eq. 56's probe points (the fixed keyframes' static points the window does not see) at most this
  /// many times the window's points (LocalMapping.MaxProbePointRatio, [0, 1000]; 0: no limit), an even
  /// stride through them when more. Every fixed keyframe of a revisited room brings its own, so they
  /// grow to 3x the first lap's (issue 32); a ratio, not a count
  double max_probe_point_ratio = 0.0;
  /// solver iterations per state step (LocalMapping.Iterations, [1, 1000])
  int ba_iterations = 10;
  /// Robust VIBA (Mapping.RobustBeta, 0/1): 1 alternates the state/point step with the closed-form
  /// Gamma/B updates of Eq. 53-57, deletes the points that end dynamic and writes Gamma back to the
  /// keyframes; 0 runs the plain VIBA on tracking's Gamma and the points' beta (an ablation).
  bool robust_beta = true;
  /// state/point <-> Gamma/B alternations of Eq. 50 (LocalMapping.Alternations, [1, 100])
  int alternations = 3;
  /// B <-> Gamma closed-form sweeps in each Gamma/B step (LocalMapping.ScoreSweeps, [1, 100])
  int score_sweeps = 5;
  /// lambda_d of the robust VIBA: weight of R_d (Eq. 54) against the Huber costs of a cluster's
  /// observations (LocalMapping.LambdaD, [0, 1e6])
  double lambda_d = 50.0;
  /// rho_H threshold on the whitened squared error (3 dof, 95%); c^ of Eq. 53 is not a setting but
  /// the window's mean squared error (LocalMapping.HuberChi2, [0.01, 1000])
  double huber_chi2 = 7.815;
  /// lambda_imu, weight of the bias random-walk regulariser, Eq. 58 (LocalMapping.LambdaImu, [0,
  /// 1e6])
  double lambda_imu = 1.0;
  /// map points whose beta ends below are deleted as dynamic (LocalMapping.MinPointBeta, [0, 1])
  double min_point_beta = 0.5;
  /// Robust VIBA: a cluster's gamma moves only on the window's evidence about it (Eq. 56 depth
  /// samples, or reprojection residuals of points seen from two or more keyframes), and a point seen
  /// once, in a cluster without such evidence, keeps its beta. Without it, Eq. 54's smoothness pulls
  /// a cluster nothing observes (revealed behind an occluder) towards its dynamic neighbours and
  /// Eq. 57 deletes its points (LocalMapping.ScoresNeedEvidence, 0/1)
  bool scores_need_evidence = true;
  /// The visual-inertial BAs of the IMU refinement and of loop closing (full BA, welding BA) weight
  /// the reprojection edges by the camera noise estimated from their residuals (the variance factor
  /// of optim::visualVarianceFactor) instead of the 1 px-per-pyramid-level model, so camera and IMU
  /// count by their actual noise (LocalMapping.VisualVarianceEstimation, 0/1)
  bool visual_variance_estimation = true;
  /// a keyframe is culled when this fraction of its points is seen by >= 3 other keyframes
  /// (LocalMapping.RedundantRatio, [0.5, 1])
  double redundant_ratio = 0.9;
  /// With the IMU initialised, a keyframe is culled only when its neighbours in time are at most this
  /// far apart (s), so the merged preintegration stays short; before the initialisation 0.5 s.
  /// Longer spans let revisits cull the keyframes earlier passes made redundant, so a run of many laps
  /// keeps a bounded map (LocalMapping.CullMaxImuSpan, [0.1, 10])
  double cull_max_imu_span_s = 0.5;
  /// With the IMU initialised, a keyframe at least this much older than the keyframe being processed
  /// (s), and its next keyframe as old, is culled when redundant whatever the span of its neighbours
  /// in time: its IMU link is cut instead of merged (a gap in the old chain; the keyframe's neighbours
  /// stay held by their points). The recent chain (local BA's inertial window, the IMU refinements)
  /// keeps every link. A robot revisiting a room then keeps a bounded number of keyframes per place
  /// instead of about two a second (LocalMapping.CullImuCutAge, [0, 1e6]; 0: never, the span rule
  /// holds for every keyframe)
  double cull_imu_cut_age_s = 0.0;
  /// In a map started at the IMU's prediction after a loss, the inertial local BA holds the map's
  /// gauge keyframe (its first) in pose and biases only and optimises its velocity: that keyframe
  /// begins at the IMU's dead-reckoned state, its velocity off by the drift of the loss; held (0, as
  /// before), the window's inertial links pass that error on to its keyframes and tracking, linked
  /// to them, follows it between keyframes (issue 28). The first map's gauge keeps the velocity of
  /// the IMU initialisation either way. Off by default until measured on more seeds: ltlo_s3
  /// realsense 13.16 -> 11.06 mm with it, ltlo_s3 ideal 7.89 -> 10.13 mm (docs/results.md)
  /// (LocalMapping.GaugeVelocityFree, 0/1)
  bool gauge_velocity_free = false;
  /// With LocalMapping.GaugeVelocityFree: the gauge's velocity is estimated with a prior about the
  /// dead-reckoned velocity the map started with, its standard deviation that of the IMU's
  /// prediction (the tracker's propagated covariance with the accelerometer-bias drift over the
  /// loss, map::MapOrigin::sigma_velocity_m_s). A map started after a short loss, whose first
  /// keyframes see little, keeps about the dead reckoning (as held); after a long loss the window's
  /// vision takes over (as free). 0: free, no prior (issue 28) (LocalMapping.GaugeVelocityPrior, 0/1)
  bool gauge_velocity_prior = false;
  /// Estimate the camera-IMU time offset online (what IMU.TimeOffset left), from the keyframe
  /// rotations after each local BA against the gyroscope (mapping/time_offset_estimator.h); tracking
  /// cuts the frames' IMU intervals with it (LocalMapping.EstimateTimeOffset, 0/1)
  bool estimate_time_offset = true;
  /// Prior sigma of that estimate around IMU.TimeOffset (s): how far the calibration may be off
  /// (LocalMapping.TimeOffsetPriorSigma, [1e-4, 0.2]); an estimate beyond 3 sigma is warned about
  double time_offset_prior_sigma_s = 0.025;
  /// Keyframe links the estimate uses, newest first (LocalMapping.TimeOffsetWindow, [3, 1000])
  int time_offset_window = 40;

  static LocalMappingOptions load(const SettingsFile& file);
};

/// Static-only place recognition and loop correction.
struct LoopOptions {
  /// run loop closing at all (Loop.Enabled, 0/1)
  bool enabled = true;
  double min_static_ratio = 0.80;  ///< keyframes with a static image fraction below are not used
                                   ///< for place recognition (Loop.MinStaticRatio, [0, 1])
  /// consecutive consistent candidates before verification (Loop.MinConsistency, [1, 20])
  int min_consistency = 3;
  /// 3-D-3-D inliers to accept a loop (Loop.MinInliers, [3, 10000])
  int min_inliers = 20;
  /// 3-D distance of an inlier after alignment, m (Loop.InlierThreshold, [0.001, 10])
  double inlier_threshold_m = 0.05;
  /// iterations of the vision-only full BA after a loop (Loop.FullBaIterations, [1, 1000])
  int full_ba_iterations = 10;
  /// With the IMU, the full BA also optimises the gravity direction and hands it to tracking and
  /// local mapping (the keyframes carry the BA's biases): the IMU initialisation and its refinements
  /// each saw one window, which a long occlusion can leave 0.3-0.5 deg off (Loop.FullBaGravity, 0/1)
  bool full_ba_gravity = true;
  /// A map started at the IMU's prediction after tracking was lost (map::MapOrigin) rejoins the map
  /// it came from when one of its keyframes matches that map's points around its pose within the
  /// dead reckoning's uncertainty: a guided search, gated like Tracking.Reacquire, instead of
  /// waiting for BoW place recognition (Loop.Rejoin, 0/1)
  bool rejoin = true;
  /// The rejoin also searches with the keyframe's best covisibles of its own map, pooled into one
  /// view by their relative poses (pooled_place_match.h): under a long occlusion one keyframe sees
  /// too little of the static world to accept or to fix the yaw. Keyframes pooled, the keyframe
  /// itself included (Loop.RejoinPool; 1: the keyframe alone)
  int rejoin_pool = 5;
  /// When a map started after a loss meets the map it came from (rejoin or merge), the IMU
  /// preintegrated across the loss links the two keyframes it spans, so the full VI BA spreads the
  /// correction over the dead-reckoned stretch; a map left between two such losses is merged with
  /// the later one on that link (Loop.BridgeLosses, 0/1)
  bool bridge_losses = true;
  /// Once the IMU is initialised, a keyframe for which BoW finds no loop also searches the older
  /// keyframes of its map near its own pose (not its covisibles), within the drift it may have
  /// gathered since: the same guided search as the rejoin, so loops do not depend on the
  /// vocabulary alone (Loop.Proximity, 0/1)
  bool proximity = true;
  /// standard deviation of that drift, m (Loop.ProximitySigma, [0.005, 5])
  double proximity_sigma_m = 0.10;
  /// The proximity search looks at keyframes at least this old, s (Loop.ProximityMinAge, [0, 3600]):
  /// younger ones are still covisible with the keyframe, so a match with them closes no loop
  double proximity_min_age_s = 10.0;
  /// and at most this far from the keyframe, m (Loop.ProximityMaxDistance, [0.1, 100]): the generated
  /// rooms' laps return within 0.2-1.5 m of an old keyframe (check_loops.py on static/mtlo/ltlo/carried
  /// seeds 1-3); a larger space, or a wider lap, needs more
  double proximity_max_distance_m = 2.0;
  /// Largest position sigma of the dead reckoning a map's rejoin still searches by guided matching,
  /// m (Loop.RejoinMaxSigma, [0.01, 100]): 3 sigma reaches 3 m, a room's scale; beyond it only BoW
  /// place recognition can merge the map
  double rejoin_max_sigma_m = 1.0;
  /// With the IMU's gravity known, a BoW loop within one map may move the current keyframe by at
  /// most 3 Loop.ProximitySigma plus this share of the path the map's keyframes travelled from the
  /// loop keyframe to it; a larger correction is a place that only looks the same (two door leaves
  /// of one texture 4.6 m apart: a 4.3 m correction, issue 32), not drift
  /// (Loop.MaxCorrectionShare, [0, 10]; 0: no limit)
  double max_correction_share = 0.0;
  /// With an IMU, a BoW loop within one map is closed only once the IMU is initialised: only then
  /// can Loop.MaxCorrectionShare bound the correction by the drift, and a map's first seconds may
  /// rest on a mover (an occluded start's provisional points; a loop of its 7th keyframe onto its
  /// first, 1.1 s apart, moved the map by 0.44 m, issue 32). ORB-SLAM3 waits likewise
  /// (Loop.WaitForImu, 0/1; no effect without an IMU)
  bool wait_for_imu = false;
  /// The full BA after a loop or merge sees only the matches of that one keyframe; the keyframes
  /// that follow keep observing the old side. This many keyframes after a correction the full BA
  /// runs once more, with that evidence (Loop.RefineKeyFrames; 0: off)
  int refine_keyframes = 10;
  /// The loop closer's full BAs, each counted as the keyframes of its map (its cost grows with
  /// them), at most this many per keyframe of the run so far. A correction whose full BA does not
  /// fit keeps the correction alone for now, and the full BA runs once the budget allows (with
  /// what the keyframes since observed, as the refining one). On a long run that closes a loop on
  /// every lap a full BA per loop grows with the map; this bounds the cost per keyframe
  /// (issue 32). Merges always run theirs (Loop.FullBaBudget, [0, 1000]; 0: no limit)
  double full_ba_budget = 0.0;
  /// Once the run has ended (System::shutdown after the last frame, not on an interrupt), one more
  /// full BA of every map with at least 3 keyframes, with everything observed up to the end: the
  /// final trajectory then no longer depends on whether a late loop happened to close and start a
  /// full BA (a marginal loop of the last lap decided 1-1.2 mm of 45 s runs, stop 45). The online
  /// poses are not changed (Loop.FinalFullBa, 0/1)
  bool final_full_ba = false;

    /// A loaded atlas's keyframes are the world's reference: every optimisation holds their poses
  /// (local and full BAs, loop corrections, seam welding), so a run in a loaded atlas stays in its
  /// world frame and the map it loaded stays as it was estimated (Loop.HoldLoadedMap, 0/1; 0: they
  /// are optimised with the new keyframes, and the world may move by centimetres)
  bool hold_loaded_map = true;

static LoopOptions load(const SettingsFile& file);
};

/// Dense coarse-to-fine alignment of the initial segmentation and state (thesis Eq. 59-64).
struct DenseOptions {
  /// Base resolution of the dense pyramid and of the segmentation labels, px: Dense.Resolution
  /// "<width>x<height>", each side in [16, 4096], the camera's divided by an integer (DESIGN.md:
  /// 320x240, QVGA).
  int width = 320;
  int height = 240;
  /// levels, each half the previous (Dense.PyramidLevels, [1, 8]; the coarsest level keeps at least
  /// 8 px per side)
  int pyramid_levels = 3;
  /// Gauss-Newton iterations per level and alternation (Dense.IterationsPerLevel, [1, 100])
  int iterations_per_level = 5;
  /// state <-> Gamma alternations per level (Dense.Alternations, [1, 20])
  int alternations = 2;
  /// finest level the state is solved on, 0 = Dense.Resolution (Dense.FinestLevel, [0,
  /// Dense.PyramidLevels - 1]); the last Gamma step runs there too
  int finest_level = 1;
  /// Gauss-Newton on a level stops once the image motion still to come is at most this, px of that
  /// level: the motion of a step is the camera-frame rotation and translation of the step at a point
  /// 0.5 m away, and what is still to come is estimated from the last two steps of the level, step
  /// rho / (1 - rho) with rho = step / previous step (no estimate, so no stop, while rho >= 0.9 or
  /// after the level's first step). 0.01 px is 0.04 mm and 0.004 deg on level 1 of a VGA input, far
  /// below a frame's dense error of about 1 mm and the features' precision
  /// (Dense.StepTolerance, [0, 10]; 0 = always Dense.IterationsPerLevel steps)
  double step_tolerance_px = 0.01;
  /// c^, the price per pixel of calling it dynamic in Eq. 60 (the (1 - gamma) c^ of Eq. 53), in
  /// units of the Cauchy penalty F: a cluster whose mean F per pixel exceeds it leans dynamic
  /// (Dense.DynamicCost, [0, 1000])
  double dynamic_cost = 0.25;
  /// a pixel whose warped point lies this far behind the previous frame's depth was hidden there
  /// (disoccluded since, e.g. behind a box moving aside): it gives no residual, evidence or prior,
  /// m; above any object's motion in one frame, below the depth steps around it
  /// (Dense.OcclusionGap, [0.01, 10])
  double occlusion_gap_m = 0.1;
  /// lambda_d of the tracking initialisation (Eq. 59): the weight of R_d (Eq. 54: temporal prior
  /// and smoothness over V_i) against the per-pixel mean of Eq. 60; LocalMapping.LambdaD weighs
  /// the same term in local mapping's Eq. 50, whose data term has another scale (Dense.LambdaD,
  /// [0, 1e6])
  double lambda_d = 0.1;
  /// whitened motion-prior residual (chi^2) above which the dense state is rejected and the
  /// prediction kept (Dense.MaxPriorChi2, [0.1, 1e9])
  double max_prior_chi2 = 30.0;
  /// The Gamma step's second baseline: an earlier frame, at least this long before the current
  /// one (the newest such frame of a few kept every half of it), also judges the clusters: each
  /// cluster's mean Eq. 60 cost against that frame at the same state is a second data coefficient,
  /// and the larger of the two counts. A mover that keeps pace with the camera shifts a pixel or two
  /// and a centimetre of depth between frames, which the noise hides, but ten times that over the
  /// baseline. Only with the IMU term (the poses between come from the IMU); after a map jump of the
  /// previous pose the kept frames go. s; 0: the previous frame alone (Dense.ReferenceBaseline,
  /// [0, 10])
  double reference_baseline_s = 0.3;
  /// standard deviation of the previous frame's velocity, m/s: widens the IMU term of Eq. 59 (the
  /// previous state is held fixed) and sets the constant-velocity translation prior, sigma dt
  /// (Dense.PriorVelocitySigma, [1e-4, 10])
  double prior_velocity_sigma_m_s = 0.05;
  /// standard deviation of the change of angular rate between frames without a gyroscope (RGB-D
  /// only: constant angular rate), rad/s (Dense.PriorAngularRateSigma, [1e-4, 100])
  double prior_angular_rate_sigma_rad_s = 0.5;
  /// standard deviation of the gyroscope bias before the IMU is initialised (the gyroscope rotation
  /// prior), rad/s (Dense.PriorGyroBiasSigma, [0, 1])
  double prior_gyro_bias_sigma_rad_s = 0.01;

  static DenseOptions load(const SettingsFile& file);
};

/// Visual-inertial initialisation (gravity direction, velocities, biases; scale known from depth).
struct ImuInitOptions {
  /// map age before the first initialisation, s (ImuInit.MinTime, [0.1, 100])
  double min_time_s = 2.0;
  /// keyframes needed for it (ImuInit.MinKeyFrames, [3, 1000])
  int min_keyframes = 10;
  /// Before the initialisation, keyframes come at least every MinTime / (MinKeyFrames - 1) s, so the
  /// IMU initialises as soon as MinTime of motion is covered (about 2 s) rather than after
  /// MinKeyFrames keyframes at KF.MaxInterval; an occlusion in the first seconds then meets an
  /// initialised IMU (ltlo seed 2: 0.13 -> 0.01-0.03 m, seed 3: 2.2 -> 0.06-0.26 m threaded; static
  /// seeds 1-3 0.3-0.6 mm better). 0: keyframes by KF.* alone (ImuInit.EarlyKeyFrames, 0/1)
  bool early_keyframes = true;
  /// Initialise the IMU from rest when the map starts still (ImuInit.FromRest, 0/1): once the
  /// zero-velocity test (Tracking.Zupt*) has held for ImuInit.RestTime since the map's last
  /// keyframe, tracking makes a keyframe at rest and local mapping takes gravity from the mean
  /// accelerometer reading, the gyro bias from the mean gyro reading and zero velocity (scale comes
  /// from depth), instead of waiting for motion. The keyframe is made by a frame held at rest, so it
  /// needs Tracking.Zupt. 0: the initialisation waits for ImuInit.MinTime of keyframes (motion)
  bool from_rest = false;
  /// Initialise the IMU from the rest before the first map (ImuInit.FromPreMapRest, 0/1): when the
  /// view was too poor for a map while the robot rested and then moved (Tracking.PreMapImuPose dead-
  /// reckons that wait), the map starts moving, so ImuInit.FromRest does not apply and the full
  /// initialisation needs ImuInit.MinTime of static view, which a box arriving soon after the
  /// start cuts short. The rest already gave gravity and the gyro bias: once the map's first
  /// keyframes span ImuInit.PreMapMinTime (at least 3 keyframes, static view), the inertial-only
  /// initialisation runs on them with gravity held at the rest's and the gyro bias's prior at the
  /// rest's mean reading (its sigma IMU.NoiseGyro / sqrt(rest)), estimating the velocities and
  /// the accelerometer bias. The map's own initialisation (and its refinements) follows once its
  /// keyframes span ImuInit.MinTime of static view, as without it.
  /// 0: the map's own initialisation alone
  bool from_pre_map_rest = false;
  /// Keyframe time span it needs, s (ImuInit.PreMapMinTime, [0.1, 100])
  double pre_map_min_time_s = 0.5;
  /// Rest needed for it, s: the gyro bias from T s of rest has a standard deviation of
  /// IMU.NoiseGyro / sqrt(T) per axis (ImuInit.RestTime, [0.2, 60])
  double rest_time_s = 2.0;
  /// inertial-only optimisation iterations (ImuInit.Iterations, [1, 1000])
  int iterations = 10;
  /// Strength of the zero-mean priors on b_g and b_a, counted in IMU readings: each prior has the
  /// variance of one reading's noise (IMU.NoiseGyro / IMU.NoiseAcc squared times IMU.Frequency)
  /// divided by this, plus the bias random walk (IMU.GyroWalk / IMU.AccWalk) over the window
  /// (optim::biasPriorInformation); 0: no prior (ImuInit.BiasPriorSamples, [0, 1e6])
  double bias_prior_samples = 1.0;
  /// Refine the estimate at the delays after the first initialisation with a full visual-inertial BA
  /// (poses, velocities, biases, gravity direction and points; scale fixed by depth); 0: re-run the
  /// inertial-only initialisation on the current poses, the ablation (ImuInit.VisualInertialRefinement,
  /// 0/1)
  bool visual_inertial_refinement = true;
  /// iterations per pass of the refinement BA (two passes: robust, then without outliers)
  /// (ImuInit.RefineIterations, [1, 1000])
  int refine_iterations = 10;
  /// keyframes the refinement BA optimises at most (the latest of the IMU chain; observers of their
  /// points beyond are held), which bounds its cost (ImuInit.RefineMaxKeyFrames, [3, 10000])
  int refine_max_keyframes = 60;
  /// Besides the refinements at +5 s and +15 s, refine again once the newest keyframe is this much
  /// later (keyframe time) than the last estimate: always until the +5 s refinement (the sigma
  /// holds the poses exact, a lower bound for a short window), afterwards while the estimate's
  /// posterior acceleration sigma (optim::inertialAccelerationCovariance) is above
  /// Tracking.AccBiasSigma; an estimate from a short window improves quickly as the window grows
  /// and turns, so a few refinements suffice. s;
  /// 0: only the scheduled refinements (ImuInit.RefineInterval, [0, 100])
  double refine_interval_s = 1.0;
  /// An initialisation or refinement ends at the newest keyframe whose static share of the view
  /// with depth (KeyFrame::staticAreaRatio) is at least this: while an occluder fills the view,
  /// vision fixes the keyframe poses too loosely for gravity and the biases. 0: every keyframe
  /// (ImuInit.MinStaticRatio, [0, 1])
  double min_static_ratio = 0.5;
  /// Until the first scheduled refinement (+5 s), local BA holds the accelerometer bias of its held
  /// keyframes only to max(Tracking.AccBiasSigma, the estimate's acceleration sigma) instead of
  /// exactly (optim::LocalBaProblem::held_acc_bias_sigma_m_s2): an initialisation from the first
  /// ~2 s is not trusted more than it is known, so its error does not bend the early map.
  /// With ImuInit.EarlyKeyFrames (ltlo_s2 0.014 -> 0.009 m); off by default, as without early
  /// keyframes it cost ltlo_s1 2.7 mm (0.017 -> 0.020 m).
  /// 0: held exactly from the first initialisation (ImuInit.LooseEarlyBias, 0/1)
  bool loose_early_bias = false;
  /// A first initialisation (in motion) whose accelerometer bias is larger than this (after the
  /// visual-inertial BA, or inertial-only without it) is rejected before anything of the map
  /// changes, and the next one starts after its keyframes:
  /// no consumer IMU is that far off (the BMI055 of a D435i: 70 mg = 0.69 m/s^2 at most), so the
  /// tracked poses it was fitted to are wrong, e.g. followed a box that held the view at an
  /// occluded start (18.6 deg of gravity, b_a 2.9 m/s^2, issue 32). m/s^2; 0: any bias accepted
  /// (ImuInit.MaxAccBias, [0, 100])
  double max_acc_bias_m_s2 = 1.5;

  static ImuInitOptions load(const SettingsFile& file);
};

/// Offline surfel fusion of the static background (reconstruct; ElasticFusion-style surfels after
/// Keller et al. 2013 and Whelan et al. 2015: projective association, confidence-weighted
/// averaging, removal of unstable surfels and of free-space violations).
struct ReconOptions {
  /// input pixels per side of one fusion pixel: depth and colour are averaged over blocks of this
  /// size (Recon.Downsample, [1, 8]; 2 = QVGA from VGA)
  int downsample = 2;
  /// depth readings outside [MinDepth, MaxDepth] are not fused, m (Recon.MinDepth, [0.01, 10])
  double min_depth_m = 0.3;
  /// (Recon.MaxDepth, [0.1, 50], above Recon.MinDepth)
  double max_depth_m = 5.0;
  /// sensor depth noise at 1 m, m; sigma(z) = DepthNoise z^2 (Recon.DepthNoise, [0, 0.1])
  double depth_noise_m = 0.0025;
  /// association window along the normal: AssocDistance + 3 sigma(z), m; covers the trajectory's
  /// own error (Recon.AssocDistance, [0, 1])
  double assoc_distance_m = 0.01;
  /// largest angle between a measured normal and the surfel's to associate them, deg
  /// (Recon.AssocMaxAngle, [1, 90])
  double assoc_max_angle_deg = 30.0;
  /// pixels seen more obliquely than this (angle between ray and normal) are not fused, deg
  /// (Recon.MaxViewAngle, [1, 89])
  double max_view_angle_deg = 75.0;
  /// surfels are stable (kept, written) once their confidence, the sum of the radial weights alpha
  /// in (0.25, 1] of the measurements fused into them, reaches this (Recon.ConfidenceStable,
  /// [0, 1000]; 0 keeps every surfel)
  double confidence_stable = 5.0;
  /// an unstable surfel older than this is removed, s (Recon.UnstableTime, [0, 1000])
  double unstable_time_s = 1.5;
  /// a stable surfel seen through (the measured surface lies behind it) in this many frames more
  /// than it was confirmed is removed; unstable ones at the first violation (Recon.FreeSpaceVotes,
  /// [0, 1000]; 0 = no free-space removal)
  int free_space_votes = 2;
  /// dynamic pixels of the segmentation are grown by this many input pixels before fusing
  /// (Recon.MaskDilation, [0, 100])
  int mask_dilation_px = 4;
  /// colour is read and fused on every n-th fused frame only; new surfels are made on those
  /// frames, the others update geometry and confidence (decoding a colour PNG costs more than
  /// fusing a frame; colour changes slowly) (Recon.ColourEvery, [1, 100]; 1 = every frame)
  int colour_every = 2;

  static ReconOptions load(const SettingsFile& file);  ///< reads and validates; throws ConfigError
  /// Range and cross-field checks of values built in code; throws ConfigError.
  void validate() const;
};

/// The live viewer (issue 30; ltlo/viewer/viewer.h): rate, picture size and the 3-D panel's view.
struct ViewerOptions {
  /// pictures per second of sequence time (Viewer.Fps, [0.5, 60])
  double fps = 10.0;
  /// each of the two panels, px (Viewer.PanelWidth [160, 1920], Viewer.PanelHeight [120, 1080])
  int panel_width = 480;
  int panel_height = 360;
  /// JPEG quality of the HTTP stream (Viewer.JpegQuality, [10, 100])
  int jpeg_quality = 80;
  /// map point size in the 3-D panel, px (Viewer.PointSize, [1, 10])
  int point_size_px = 2;
  /// the 3-D panel's camera: behind and above the current camera, m (Viewer.FollowDistance,
  /// Viewer.FollowHeight, [0, 50])
  double follow_distance_m = 3.0;
  double follow_height_m = 1.5;
  /// a loop closure or map merge flashes its edges for this long, s of sequence time
  /// (Viewer.LoopFlashSeconds, [0, 30]; at least one picture)
  double loop_flash_s = 2.0;
  /// while a loop flashes, the 3-D panel pulls back to show every keyframe and the current camera,
  /// so the new edge is in view however far back in the map it reaches (Viewer.LoopOverview; off:
  /// the following camera stays)
  bool loop_overview = true;
  /// The viewer thread's nice value above the SLAM threads' (Viewer.ThreadNice, [0, 19]; 0: the
  /// same priority): it renders in the time they leave and drops pictures it has no time for
  /// (counted). Measured on 2 cores, 45 s ltlo_s1 as fast as it runs (CPU-bound, about 75 FPS), video
  /// + HTTP + pose stream against no viewer, three alternating pairs, tracking median / wall time:
  /// nice 0 +0.5..+1.9 ms / +7..+16 %, 450 of 450 pictures; nice 10 +0.2..+0.9 ms / +3..+10 %,
  /// 405-430; nice 19 -0.4..+0.9 ms / -3..+6 %, 397-407. A 30 Hz live run leaves the viewer time.
  int thread_nice = 19;

  static ViewerOptions load(const SettingsFile& file);  ///< reads and validates; throws ConfigError
};

/// One "--set Key=Value" of a program's command line: replaces Key of the settings file (or of the
/// sequence's calib.yaml for calibration keys) before loading, validated exactly like the file.
struct SettingOverride {
  std::string key;
  std::string value;  ///< YAML scalar text ("0", "0.5", "320x240")
  /// Splits "Key=Value" at the first '='; throws ConfigError "--set <text>: expected Key=Value"
  /// when either side is empty.
  static SettingOverride parse(const std::string& text);
};

/// Everything a run is configured with.
struct Settings {
  /// the algorithm settings file
  std::string config_path;
  /// where the calibration came from (calib.yaml or config_path)
  std::string calib_path;
  /// Camera.*, DepthMapFactor, IMU.*
  SensorCalib calib;
  OrbOptions orb;
  SegmentationOptions segmentation;
  KeyFrameOptions keyframe;
  TrackingOptions tracking;
  LocalMappingOptions local_mapping;
  LoopOptions loop;
  DenseOptions dense;
  ImuInitOptions imu_init;
  ReconOptions recon;
  ViewerOptions viewer;
  SequenceOptions sequence;
  /// "<file>: <key>" for every key no option asked for (also logged as warnings at load).
  std::vector<std::string> unknown_keys;
  /// The --set overrides applied at load, in command-line order (also in describe()).
  std::vector<SettingOverride> overrides;

  /// Loads `config_path` (config_yaml/*.yaml). The calibration comes from `calib_path` (a
  /// sequence's calib.yaml) when it is not empty, otherwise from the Camera.* / DepthMapFactor /
  /// IMU.* keys of the config file itself (TUM / OpenLORIS style); with a calib.yaml, those keys
  /// in the config are ignored with one info line. `overrides` replace keys of the files first
  /// (SettingsFile::setOverride; a later one wins); an override no setting reads (a retired key
  /// too) is a ConfigError (a typo on the command line would otherwise change nothing). Throws
  /// ConfigError.
  static Settings load(const std::string& config_path, const std::string& calib_path = "",
                       const std::vector<SettingOverride>& overrides = {});

  /// Checks every range and cross-field rule on the values in memory (settings built in code);
  /// throws ConfigError "settings: <key> = <value>, expected <range>".
  void validate() const;

  /// One "<key> = <value>" line per setting, calibration first, in YAML-key terms.
  std::string describe() const;
  /// Logs describe() at info level, one log line per setting.
  void log() const;
};

}  // namespace ltlo
