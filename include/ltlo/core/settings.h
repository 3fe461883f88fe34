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
/// An unknown key (usually a typo) is logged as a warning and listed in Settings::unknown_keys.
#include <string>
#include <vector>

#include "ltlo/core/calib.h"
#include "ltlo/core/sequence_options.h"

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
  /// lambda_d, weight of R_d (gamma prior and smoothness over V_i), Eq. 54-55 (Seg.LambdaD, [0,
  /// 1e6])
  double lambda_d = 1.0;
  /// lambda_s, weight of R_s (beta prior), Eq. 54 (Seg.LambdaS, [0, 1e6])
  double lambda_s = 1.0;
  /// lambda_p, 1/m: gamma~ = 1 - lambda_p * mean depth difference, Eq. 56 (Seg.LambdaP, [0, 1000])
  double lambda_p = 2.0;
  /// lambda_phi in beta~ = phi(lambda_phi, mean gamma), Eq. 57 (Seg.LambdaPhi, [0, 0.99])
  double lambda_phi = 0.5;
  /// clusters with gamma above this give tracking features and new map points (Seg.StaticThreshold,
  /// [0, 1])
  double static_threshold = 0.5;

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
  /// a keyframe at least this often, s; bounds IMU preintegration time (KF.MaxInterval, [0.01,
  /// 100])
  double max_interval_s = 1.0;

  static KeyFrameOptions load(const SettingsFile& file);
};

/// Robust visual-inertial BA over a sliding window (thesis Eq. 50-58) and map maintenance.
struct LocalMappingOptions {
  /// keyframes optimised (their covisible neighbours held fixed) (LocalMapping.WindowSize, [2,
  /// 100])
  int window_size = 10;
  /// solver iterations per state step (LocalMapping.Iterations, [1, 1000])
  int ba_iterations = 10;
  /// state/point <-> Gamma/B alternations of Eq. 50 (LocalMapping.Alternations, [1, 100])
  int alternations = 3;
  /// rho_H threshold on the whitened squared error (3 dof, 95%) (LocalMapping.HuberChi2, [0.01,
  /// 1000])
  double huber_chi2 = 7.815;
  /// c^ in (1-beta)^2 (1-gamma)^2 rho_H(c^), the price of calling an observation dynamic, Eq. 53
  /// (LocalMapping.DynamicCost, [0.01, 1000])
  double dynamic_cost = 7.815;
  /// lambda_imu, weight of the bias random-walk regulariser, Eq. 58 (LocalMapping.LambdaImu, [0,
  /// 1e6])
  double lambda_imu = 1.0;
  /// map points whose beta ends below are deleted as dynamic (LocalMapping.MinPointBeta, [0, 1])
  double min_point_beta = 0.5;
  /// a keyframe is culled when this fraction of its points is seen by >= 3 other keyframes
  /// (LocalMapping.RedundantRatio, [0.5, 1])
  double redundant_ratio = 0.9;

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
  /// and smoothness over V_i) against the per-pixel mean of Eq. 60; Seg.LambdaD weighs the same
  /// term in local mapping's Eq. 50, whose data term has another scale (Dense.LambdaD, [0, 1e6])
  double lambda_d = 0.1;
  /// whitened motion-prior residual (chi^2) above which the dense state is rejected and the
  /// prediction kept (Dense.MaxPriorChi2, [0.1, 1e9])
  double max_prior_chi2 = 30.0;
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
  /// inertial-only optimisation iterations (ImuInit.Iterations, [1, 1000])
  int iterations = 10;
  /// information of the zero prior on b_g, 1/(rad/s)^2 (ImuInit.PriorGyroBias, [0, 1e12])
  double prior_gyro_bias = 1e2;
  /// information of the zero prior on b_a, 1/(m/s^2)^2 (ImuInit.PriorAccBias, [0, 1e12])
  double prior_acc_bias = 1e5;

  static ImuInitOptions load(const SettingsFile& file);
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
  LocalMappingOptions local_mapping;
  LoopOptions loop;
  DenseOptions dense;
  ImuInitOptions imu_init;
  SequenceOptions sequence;
  /// "<file>: <key>" for every key no option asked for (also logged as warnings at load).
  std::vector<std::string> unknown_keys;

  /// Loads `config_path` (config_yaml/*.yaml). The calibration comes from `calib_path` (a
  /// sequence's calib.yaml) when it is not empty, otherwise from the Camera.* / DepthMapFactor /
  /// IMU.* keys of the config file itself (TUM / OpenLORIS style); with a calib.yaml, those keys
  /// in the config are ignored with one info line. Throws ConfigError.
  static Settings load(const std::string& config_path, const std::string& calib_path = "");

  /// Checks every range and cross-field rule on the values in memory (settings built in code);
  /// throws ConfigError "settings: <key> = <value>, expected <range>".
  void validate() const;

  /// One "<key> = <value>" line per setting, calibration first, in YAML-key terms.
  std::string describe() const;
  /// Logs describe() at info level, one log line per setting.
  void log() const;
};

}  // namespace ltlo
