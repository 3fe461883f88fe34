#include "ltlo/core/settings.h"

#include <algorithm>
#include <cstdio>
#include <optional>
#include <sstream>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/settings_file.h"

namespace ltlo {
namespace {

std::string numberText(double value) {
  std::ostringstream os;
  os << value;
  return os.str();
}

// ---- One table per option struct ------------------------------------------------------------
// Each visit*() lists key, field and range once; the same table drives loading from a file,
// validating values built in code and describing the settings (so they cannot drift apart).
// `O` is the struct or its const version; visitors take the field by (const) reference.

template <typename O, typename V>
void visitOrb(O& o, V& v) {
  v.integer("ORBextractor.nFeatures", o.num_features, 50, 20000);
  v.real("ORBextractor.scaleFactor", o.scale_factor, 1.05, 2.0);
  v.integer("ORBextractor.nLevels", o.num_levels, 1, 16);
  v.integer("ORBextractor.iniThFAST", o.ini_th_fast, 1, 255);
  v.integer("ORBextractor.minThFAST", o.min_th_fast, 1, 255);
  if (o.min_th_fast > o.ini_th_fast) {
    v.fail("ORBextractor.minThFAST", std::to_string(o.min_th_fast),
           "an integer in [1, ORBextractor.iniThFAST = " + std::to_string(o.ini_th_fast) + "]");
  }
}

template <typename O, typename V>
void visitSegmentation(O& o, V& v) {
  v.boolean("Seg.Enable", o.enable);
  v.boolean("Seg.DenseInit", o.dense_init);
  v.integer("Seg.Clusters", o.num_clusters, 2, 255);  // segmentation::kMaxClusters (8-bit labels)
  v.integer("Seg.KMeansIterations", o.kmeans_iterations, 1, 50);
  v.real("Seg.MaxNeighbourGap", o.max_neighbour_gap_m, 0.001, 10.0);
  v.real("Seg.AlphaIntensity", o.alpha_intensity, 0.001, 10.0);
  v.real("Seg.NoiseWeightIntensity", o.noise_weight_intensity, 0.0, 1e6);
  v.real("Seg.NoiseWeightDepth", o.noise_weight_depth, 0.0, 1e6);
  v.real("Seg.SigmaIntensity", o.sigma_intensity, 1e-6, 1.0);
  v.real("Seg.SigmaDepth", o.sigma_depth_m, 1e-6, 1.0);
  v.real("Seg.CauchyC", o.cauchy_c, 1e-6, 1000.0);
  v.real("Seg.LambdaS", o.lambda_s, 0.0, 1e6);
  v.real("Seg.LambdaP", o.lambda_p, 0.0, 1000.0);
  v.real("Seg.LambdaPhi", o.lambda_phi, 0.0, 0.99);
  v.real("Seg.StaticThreshold", o.static_threshold, 0.0, 1.0);
  v.boolean("Seg.AffineBrightness", o.affine_brightness);
  v.real("Seg.AffineBrightnessPrior", o.affine_brightness_prior, 0.0, 100.0);
  v.boolean("Seg.HindsightMasks", o.hindsight_masks);
  v.integer("Seg.HindsightMinPoints", o.hindsight_min_points, 1, 1000);
  v.real("Seg.HindsightRayTolerance", o.hindsight_ray_tolerance_m, 0.001, 1.0);
  v.real("Seg.HindsightVoteRadius", o.hindsight_vote_radius_m, 0.01, 10.0);
  v.boolean("Seg.HindsightToStatic", o.hindsight_to_static);
  v.real("Seg.HindsightStaticShare", o.hindsight_static_share, 0.5, 1.0);
  v.boolean("Seg.HindsightFreeSpace", o.hindsight_free_space);
  v.integer("Seg.HindsightFreeSpaceViews", o.hindsight_free_space_views, 1, 20);
  v.integer("Seg.HindsightFreeSpaceMaxViews", o.hindsight_free_space_max_views, 0, 100000);
  v.real("Seg.HindsightFreeSpaceFrameInterval", o.hindsight_free_space_frame_interval_s, 0.0, 60.0);
  v.boolean("Seg.HindsightRejudge", o.hindsight_rejudge);
  v.real("Seg.HindsightRejudgeMinShift", o.hindsight_rejudge_min_shift_px, 0.0, 100.0);
  v.real("Seg.HindsightFreeSpaceTolerance", o.hindsight_free_space_tolerance_m, 0.0, 1.0);
}

template <typename O, typename V>
void visitKeyFrame(O& o, V& v) {
  v.real("KF.MaxOverlap", o.max_overlap, 0.05, 0.99);
  v.integer("KF.MinTrackedPoints", o.min_tracked_points, 0, 10000);
  v.real("KF.WeakMinInterval", o.weak_min_interval_s, 0.0, 10.0);
  v.real("KF.MaxInterval", o.max_interval_s, 0.01, 100.0);
  v.integer("KF.MinInliers", o.min_inliers, 3, 10000);
  v.integer("KF.MinInliersInertial", o.min_inliers_inertial, 3, 10000);
  v.real("KF.RevisitMaxInterval", o.revisit_max_interval_s, 0.0, 100.0);
  v.real("KF.RevisitMappedShare", o.revisit_mapped_share, 0.5, 1.0);
  v.integer("KF.RevisitMinObservers", o.revisit_min_observers, 2, 100);
  v.real("KF.RevisitMaxNewShare", o.revisit_max_new_share, 0.0, 1.0);
}

template <typename O, typename V>
void visitTracking(O& o, V& v) {
  v.boolean("Tracking.InertialPoseOptimisation", o.inertial_pose_optimisation);
  v.boolean("Tracking.DenseStateWithImu", o.dense_state_with_imu);
  v.integer("Tracking.MinInliers", o.min_inliers, 6, 10000);
  v.integer("Tracking.MinInliersImu", o.min_inliers_imu, 3, 10000);
  if (o.min_inliers_imu > o.min_inliers) {
    v.fail("Tracking.MinInliersImu", std::to_string(o.min_inliers_imu),
           "an integer in [3, Tracking.MinInliers = " + std::to_string(o.min_inliers) + "]");
  }
  v.real("Tracking.MaxImuPositionSigma", o.max_imu_position_sigma_m, 0.001, 10.0);
  v.real("Tracking.AccBiasSigma", o.acc_bias_sigma_m_s2, 0.0, 10.0);
  v.real("Tracking.NewMapAfter", o.new_map_after_s, -1.0, 1000.0);
  v.integer("Tracking.MinExtendFeatures", o.min_extend_features, 10, 10000);
  v.real("Tracking.MaxLostImuInterval", o.max_lost_imu_interval_s, 0.1, 1000.0);
  v.boolean("Tracking.SmoothCarriedFrames", o.smooth_carried_frames);
  v.real("Tracking.CarriedVelocitySigma", o.carried_velocity_sigma_m_s, 0.0, 10.0);
  v.boolean("Tracking.CarriedBridge", o.carried_bridge);
  v.real("Tracking.CarriedBridgeMargin", o.carried_bridge_margin_s, 0.0, 5.0);
  v.real("Tracking.CarriedGyroBiasSigma", o.carried_gyro_bias_sigma_rad_s, 1e-9, 1.0);
  v.boolean("Tracking.Reacquire", o.reacquire);
  v.real("Tracking.ReacquireGateSigmas", o.reacquire_gate_sigmas, 1.0, 20.0);
  v.real("Tracking.ReacquireMinRotationGate", o.reacquire_min_rotation_gate_deg, 0.0, 180.0);
  v.real("Tracking.ReacquireMaxRadius", o.reacquire_max_radius_px, 5.0, 2000.0);
  v.integer("Tracking.ReacquireMinInliers", o.reacquire_min_inliers, 6, 10000);
  v.real("RGBD.VirtualBaseline", o.virtual_baseline_m, 0.001, 100.0);
  v.real("Tracking.LoadedAtlasNewMapAfter", o.loaded_atlas_new_map_after_s, -1.0, 1000.0);
  v.boolean("Tracking.LocalisationOnly", o.localisation_only);
  v.boolean("Tracking.Zupt", o.zupt);
  v.boolean("Tracking.ZuptNoKeyFrames", o.zupt_no_keyframes);
  v.real("Tracking.ZuptWindow", o.zupt_window_s, 0.1, 5.0);
  v.real("Tracking.ZuptThreshold", o.zupt_threshold, 1.0, 100.0);
  v.boolean("Tracking.ZuptVisualCheck", o.zupt_visual_check);
  v.real("Tracking.ZuptMaxDisplacement", o.zupt_max_displacement_px, 0.1, 100.0);
  v.real("Tracking.StartProvisional", o.start_provisional_s, 0.0, 1000.0);
  v.integer("Tracking.StartDynamicVotes", o.start_dynamic_votes, 1, 100);
  v.real("Tracking.StartReacquireSpeed", o.start_reacquire_speed_m_s, 0.0, 10.0);
  v.boolean("Tracking.StartRecoveryCutsImu", o.start_recovery_cuts_imu);
  v.boolean("Tracking.StartRecoveryGauge", o.start_recovery_gauge);
  v.real("Tracking.StartMotionCheck", o.start_motion_check_m_s2, 0.0, 100.0);
  v.real("Tracking.GyroRotationGate", o.gyro_rotation_gate_deg, 0.0, 180.0);
  v.boolean("Tracking.StartCarriedLost", o.start_carried_lost);
  v.boolean("Tracking.PreMapImuPose", o.pre_map_imu_pose);
  v.boolean("Tracking.NewMapVelocityPrior", o.new_map_velocity_prior);
  v.real("Tracking.NewMapVelocityTrust", o.new_map_velocity_trust_s, 0.0, 60.0);
}

template <typename O, typename V>
void visitLocalMapping(O& o, V& v) {
  v.integer("LocalMapping.WindowSize", o.window_size, 2, 100);
  v.integer("LocalMapping.MaxFixedKeyFrames", o.max_fixed_keyframes, 1, 1000);
  v.integer("LocalMapping.MaxFixedObservationsPerPoint", o.max_fixed_observations_per_point, 0, 1000);
  v.real("LocalMapping.MaxFixedObservationRatio", o.max_fixed_observation_ratio, 0.0, 1000.0);
  v.real("LocalMapping.MaxProbePointRatio", o.max_probe_point_ratio, 0.0, 1000.0);
  v.integer("LocalMapping.Iterations", o.ba_iterations, 1, 1000);
  v.boolean("Mapping.RobustBeta", o.robust_beta);
  v.integer("LocalMapping.Alternations", o.alternations, 1, 100);
  v.integer("LocalMapping.ScoreSweeps", o.score_sweeps, 1, 100);
  v.real("LocalMapping.LambdaD", o.lambda_d, 0.0, 1e6);
  v.real("LocalMapping.HuberChi2", o.huber_chi2, 0.01, 1000.0);
  v.real("LocalMapping.LambdaImu", o.lambda_imu, 0.0, 1e6);
  v.real("LocalMapping.MinPointBeta", o.min_point_beta, 0.0, 1.0);
  v.boolean("LocalMapping.ScoresNeedEvidence", o.scores_need_evidence);
  v.boolean("LocalMapping.VisualVarianceEstimation", o.visual_variance_estimation);
  v.real("LocalMapping.RedundantRatio", o.redundant_ratio, 0.5, 1.0);
  v.real("LocalMapping.CullMaxImuSpan", o.cull_max_imu_span_s, 0.1, 10.0);
  v.real("LocalMapping.CullImuCutAge", o.cull_imu_cut_age_s, 0.0, 1e6);
  v.boolean("LocalMapping.GaugeVelocityFree", o.gauge_velocity_free);
  v.boolean("LocalMapping.GaugeVelocityPrior", o.gauge_velocity_prior);
  v.boolean("LocalMapping.EstimateTimeOffset", o.estimate_time_offset);
  v.real("LocalMapping.TimeOffsetPriorSigma", o.time_offset_prior_sigma_s, 1e-4, 0.2);
  v.integer("LocalMapping.TimeOffsetWindow", o.time_offset_window, 3, 1000);
}

template <typename O, typename V>
void visitLoop(O& o, V& v) {
  v.boolean("Loop.Enabled", o.enabled);
  v.real("Loop.MinStaticRatio", o.min_static_ratio, 0.0, 1.0);
  v.integer("Loop.MinConsistency", o.min_consistency, 1, 20);
  v.integer("Loop.MinInliers", o.min_inliers, 3, 10000);
  v.real("Loop.InlierThreshold", o.inlier_threshold_m, 0.001, 10.0);
  v.integer("Loop.FullBaIterations", o.full_ba_iterations, 1, 1000);
  v.boolean("Loop.FullBaGravity", o.full_ba_gravity);
  v.boolean("Loop.Rejoin", o.rejoin);
  v.integer("Loop.RejoinPool", o.rejoin_pool, 1, 20);
  v.boolean("Loop.BridgeLosses", o.bridge_losses);
  v.boolean("Loop.Proximity", o.proximity);
  v.integer("Loop.RefineKeyFrames", o.refine_keyframes, 0, 1000);
  v.real("Loop.FullBaBudget", o.full_ba_budget, 0.0, 1000.0);
  v.boolean("Loop.FinalFullBa", o.final_full_ba);
  v.real("Loop.ProximitySigma", o.proximity_sigma_m, 0.005, 5.0);
  v.real("Loop.ProximityMinAge", o.proximity_min_age_s, 0.0, 3600.0);
  v.real("Loop.ProximityMaxDistance", o.proximity_max_distance_m, 0.1, 100.0);
  v.real("Loop.RejoinMaxSigma", o.rejoin_max_sigma_m, 0.01, 100.0);
  v.real("Loop.MaxCorrectionShare", o.max_correction_share, 0.0, 10.0);
  v.boolean("Loop.WaitForImu", o.wait_for_imu);
  v.boolean("Loop.HoldLoadedMap", o.hold_loaded_map);
}

template <typename O, typename V>
void visitDense(O& o, V& v) {
  v.resolution("Dense.Resolution", o.width, o.height, 16, 4096);
  v.integer("Dense.PyramidLevels", o.pyramid_levels, 1, 8);
  v.integer("Dense.IterationsPerLevel", o.iterations_per_level, 1, 100);
  v.integer("Dense.Alternations", o.alternations, 1, 20);
  v.integer("Dense.FinestLevel", o.finest_level, 0, 7);
  v.real("Dense.StepTolerance", o.step_tolerance_px, 0.0, 10.0);
  v.real("Dense.DynamicCost", o.dynamic_cost, 0.0, 1000.0);
  v.real("Dense.LambdaD", o.lambda_d, 0.0, 1e6);
  v.real("Dense.OcclusionGap", o.occlusion_gap_m, 0.01, 10.0);
  v.real("Dense.MaxPriorChi2", o.max_prior_chi2, 0.1, 1e9);
  v.real("Dense.ReferenceBaseline", o.reference_baseline_s, 0.0, 10.0);
  v.real("Dense.PriorVelocitySigma", o.prior_velocity_sigma_m_s, 1e-4, 10.0);
  v.real("Dense.PriorAngularRateSigma", o.prior_angular_rate_sigma_rad_s, 1e-4, 100.0);
  v.real("Dense.PriorGyroBiasSigma", o.prior_gyro_bias_sigma_rad_s, 0.0, 1.0);
  if (o.finest_level >= o.pyramid_levels) {
    v.fail("Dense.FinestLevel", std::to_string(o.finest_level),
           "an integer in [0, Dense.PyramidLevels - 1 = " + std::to_string(o.pyramid_levels - 1) + "]");
  }
  // The coarsest level (base halved levels - 1 times) must keep at least 8 px per side.
  const int coarsest_side = std::min(o.width, o.height) >> (o.pyramid_levels - 1);
  if (coarsest_side < 8) {
    int max_levels = 1;
    while ((std::min(o.width, o.height) >> max_levels) >= 8) ++max_levels;
    v.fail("Dense.PyramidLevels", std::to_string(o.pyramid_levels),
           "an integer in [1, " + std::to_string(max_levels) + "] for Dense.Resolution " +
               std::to_string(o.width) + "x" + std::to_string(o.height) +
               " (coarsest level at least 8 px)");
  }
}

template <typename O, typename V>
void visitImuInit(O& o, V& v) {
  v.real("ImuInit.MinTime", o.min_time_s, 0.1, 100.0);
  v.integer("ImuInit.MinKeyFrames", o.min_keyframes, 3, 1000);
  v.boolean("ImuInit.EarlyKeyFrames", o.early_keyframes);
  v.boolean("ImuInit.FromRest", o.from_rest);
  v.boolean("ImuInit.FromPreMapRest", o.from_pre_map_rest);
  v.real("ImuInit.PreMapMinTime", o.pre_map_min_time_s, 0.1, 100.0);
  v.real("ImuInit.RestTime", o.rest_time_s, 0.2, 60.0);
  v.integer("ImuInit.Iterations", o.iterations, 1, 1000);
  v.real("ImuInit.BiasPriorSamples", o.bias_prior_samples, 0.0, 1e6);
  v.boolean("ImuInit.VisualInertialRefinement", o.visual_inertial_refinement);
  v.integer("ImuInit.RefineIterations", o.refine_iterations, 1, 1000);
  v.integer("ImuInit.RefineMaxKeyFrames", o.refine_max_keyframes, 3, 10000);
  v.real("ImuInit.RefineInterval", o.refine_interval_s, 0.0, 100.0);
  v.real("ImuInit.MinStaticRatio", o.min_static_ratio, 0.0, 1.0);
  v.boolean("ImuInit.LooseEarlyBias", o.loose_early_bias);
  v.real("ImuInit.MaxAccBias", o.max_acc_bias_m_s2, 0.0, 100.0);
}

template <typename O, typename V>
void visitRecon(O& o, V& v) {
  v.integer("Recon.Downsample", o.downsample, 1, 8);
  v.real("Recon.MinDepth", o.min_depth_m, 0.01, 10.0);
  v.real("Recon.MaxDepth", o.max_depth_m, 0.1, 50.0);
  v.real("Recon.DepthNoise", o.depth_noise_m, 0.0, 0.1);
  v.real("Recon.AssocDistance", o.assoc_distance_m, 0.0, 1.0);
  v.real("Recon.AssocMaxAngle", o.assoc_max_angle_deg, 1.0, 90.0);
  v.real("Recon.MaxViewAngle", o.max_view_angle_deg, 1.0, 89.0);
  v.real("Recon.ConfidenceStable", o.confidence_stable, 0.0, 1000.0);
  v.real("Recon.UnstableTime", o.unstable_time_s, 0.0, 1000.0);
  v.integer("Recon.FreeSpaceVotes", o.free_space_votes, 0, 1000);
  v.integer("Recon.MaskDilation", o.mask_dilation_px, 0, 100);
  v.integer("Recon.ColourEvery", o.colour_every, 1, 100);
  if (!(o.max_depth_m > o.min_depth_m)) {
    v.fail("Recon.MaxDepth", numberText(o.max_depth_m),
           "a number in [0.1, 50] above Recon.MinDepth = " + numberText(o.min_depth_m));
  }
}

template <typename O, typename V>
void visitViewer(O& o, V& v) {
  v.real("Viewer.Fps", o.fps, 0.5, 60.0);
  v.integer("Viewer.PanelWidth", o.panel_width, 160, 1920);
  v.integer("Viewer.PanelHeight", o.panel_height, 120, 1080);
  v.integer("Viewer.JpegQuality", o.jpeg_quality, 10, 100);
  v.integer("Viewer.PointSize", o.point_size_px, 1, 10);
  v.real("Viewer.FollowDistance", o.follow_distance_m, 0.0, 50.0);
  v.real("Viewer.FollowHeight", o.follow_height_m, 0.0, 50.0);
  v.real("Viewer.LoopFlashSeconds", o.loop_flash_s, 0.0, 30.0);
  v.boolean("Viewer.LoopOverview", o.loop_overview);
  v.integer("Viewer.ThreadNice", o.thread_nice, 0, 19);
}

std::string rangeText(double min, double max) {
  return "[" + numberText(min) + ", " + numberText(max) + "]";
}

const char kResolutionExpected[] = "\"<width>x<height>\" with each side in ";

// Reads every key of a table from a settings file (SettingsFile validates type and range).
struct Loader {
  const SettingsFile& file;

  void integer(const char* key, int& value, int min, int max) {
    value = file.getInt(key, min, max);
  }
  void real(const char* key, double& value, double min, double max) {
    value = file.getDouble(key, min, max);
  }
  void boolean(const char* key, bool& value) { value = file.getBool(key); }
  void resolution(const char* key, int& width, int& height, int min, int max) {
    const std::string expected = kResolutionExpected + rangeText(min, max);
    if (!file.has(key)) file.failMissing(key, expected);
    std::string text;
    try {
      text = file.getString(key);
    } catch (const ConfigError&) {
      file.fail(key, file.valueText(key), expected);  // a number or a map instead of "WxH"
    }
    int w = 0, h = 0;
    char extra = 0;
    if (std::sscanf(text.c_str(), "%dx%d%c", &w, &h, &extra) != 2 || w < min || w > max ||
        h < min || h > max) {
      file.fail(key, "\"" + text + "\"", expected);
    }
    width = w;
    height = h;
  }
  [[noreturn]] void fail(const std::string& key, const std::string& value,
                         const std::string& expected) {
    file.fail(key, value, expected);
  }
};

// Checks values already in memory (settings built in code), with the same ranges and messages.
struct Validator {
  std::string source = "settings";

  [[noreturn]] void fail(const std::string& key, const std::string& value,
                         const std::string& expected) const {
    throw ConfigError(source + ": " + key + " = " + value + ", expected " + expected);
  }
  void integer(const char* key, int value, int min, int max) const {
    if (value < min || value > max) {
      fail(key, std::to_string(value), "an integer in " + rangeText(min, max));
    }
  }
  void real(const char* key, double value, double min, double max) const {
    if (!(value >= min && value <= max)) {
      fail(key, numberText(value), "a number in " + rangeText(min, max));
    }
  }
  void boolean(const char*, bool) const {}
  void resolution(const char* key, int width, int height, int min, int max) const {
    if (width < min || width > max || height < min || height > max) {
      fail(key, "\"" + std::to_string(width) + "x" + std::to_string(height) + "\"",
           kResolutionExpected + rangeText(min, max));
    }
  }
};

// "<key> = <value>" lines in table order.
struct Describer {
  std::ostringstream os;

  void integer(const char* key, int value, int, int) { os << key << " = " << value << "\n"; }
  void real(const char* key, double value, double, double) { os << key << " = " << value << "\n"; }
  void boolean(const char* key, bool value) { os << key << " = " << (value ? 1 : 0) << "\n"; }
  void resolution(const char* key, int width, int height, int, int) {
    os << key << " = " << width << "x" << height << "\n";
  }
  void fail(const std::string&, const std::string&, const std::string&) {}  // describe never fails
};

// The whole-settings rule: the dense pyramid base is the camera image divided by an integer.
template <typename Fail>
void checkDenseAgainstCamera(const DenseOptions& dense, const PinholeCamera& camera,
                             const std::string& calib_source, Fail&& fail) {
  if (dense.width > camera.width() || dense.height > camera.height()) {
    fail("Dense.Resolution",
         "\"" + std::to_string(dense.width) + "x" + std::to_string(dense.height) + "\"",
         "at most the camera resolution " + std::to_string(camera.width()) + "x" +
             std::to_string(camera.height()) + " (" + calib_source + ")");
  } else if (camera.width() % dense.width != 0 || camera.height() % dense.height != 0 ||
             camera.width() / dense.width != camera.height() / dense.height) {
    // The pyramid base averages s x s camera pixels (the segmentation labels use the same grid).
    fail("Dense.Resolution",
         "\"" + std::to_string(dense.width) + "x" + std::to_string(dense.height) + "\"",
         "the camera resolution " + std::to_string(camera.width()) + "x" + std::to_string(camera.height()) +
             " divided by an integer (" + calib_source + ")");
  }
}

bool isCalibrationKey(const std::string& key) {
  return key.rfind("Camera.", 0) == 0 || key.rfind("IMU.", 0) == 0 || key == "DepthMapFactor";
}

// Keys the settings had once and read no more. A file that still has one loads with one note per
// key (its value changes nothing), not the typo warning; --set of one is a ConfigError, since it
// would change nothing either.
struct RetiredKey {
  const char* key;
  const char* note;  // what took its place
};
constexpr RetiredKey kRetiredKeys[] = {
    {"Seg.LambdaD",
     "tracking's dense initial segmentation weighs R_d with Dense.LambdaD, local mapping with "
     "LocalMapping.LambdaD"},
};

const RetiredKey* retiredKey(const std::string& key) {
  for (const RetiredKey& retired : kRetiredKeys) {
    if (key == retired.key) return &retired;
  }
  return nullptr;
}

}  // namespace

OrbOptions OrbOptions::load(const SettingsFile& file) {
  OrbOptions options;
  Loader loader{file};
  visitOrb(options, loader);
  return options;
}

SegmentationOptions SegmentationOptions::load(const SettingsFile& file) {
  SegmentationOptions options;
  Loader loader{file};
  visitSegmentation(options, loader);
  return options;
}

KeyFrameOptions KeyFrameOptions::load(const SettingsFile& file) {
  KeyFrameOptions options;
  Loader loader{file};
  visitKeyFrame(options, loader);
  return options;
}

TrackingOptions TrackingOptions::load(const SettingsFile& file) {
  TrackingOptions options;
  Loader loader{file};
  visitTracking(options, loader);
  return options;
}

LocalMappingOptions LocalMappingOptions::load(const SettingsFile& file) {
  LocalMappingOptions options;
  Loader loader{file};
  visitLocalMapping(options, loader);
  return options;
}

LoopOptions LoopOptions::load(const SettingsFile& file) {
  LoopOptions options;
  Loader loader{file};
  visitLoop(options, loader);
  return options;
}

DenseOptions DenseOptions::load(const SettingsFile& file) {
  DenseOptions options;
  Loader loader{file};
  visitDense(options, loader);
  return options;
}

ImuInitOptions ImuInitOptions::load(const SettingsFile& file) {
  ImuInitOptions options;
  Loader loader{file};
  visitImuInit(options, loader);
  return options;
}

ReconOptions ReconOptions::load(const SettingsFile& file) {
  ReconOptions options;
  Loader loader{file};
  visitRecon(options, loader);
  return options;
}

ViewerOptions ViewerOptions::load(const SettingsFile& file) {
  ViewerOptions options;
  Loader loader{file};
  visitViewer(options, loader);
  return options;
}

void ReconOptions::validate() const {
  Validator validator;
  visitRecon(*this, validator);
}

SettingOverride SettingOverride::parse(const std::string& text) {
  const std::size_t equals = text.find('=');
  if (equals == std::string::npos || equals == 0 || equals + 1 == text.size()) {
    throw ConfigError("--set " + text + ": expected Key=Value (e.g. Seg.Enable=0)");
  }
  return {text.substr(0, equals), text.substr(equals + 1)};
}

namespace {

// Each --set goes into the calibration file when there is one and the key is a calibration key,
// otherwise into the config (logged with the value it replaces).
void applyOverrides(const std::vector<SettingOverride>& overrides, SettingsFile* config,
                    std::optional<SettingsFile>* calib) {
  for (const SettingOverride& o : overrides) {
    const bool in_calib = *calib && isCalibrationKey(o.key);
    const SettingsFile& target = in_calib ? **calib : *config;
    log::info("settings: --set ", o.key, " = ", o.value, " (", target.path(), " has ",
              target.has(o.key) ? target.valueText(o.key) : std::string("no such key"), ")");
    (in_calib ? **calib : *config).setOverride(o.key, o.value);
  }
}

// The calibration from the calibration file when there is one (its unknown keys warned about and
// listed), otherwise from the config.
void loadCalibration(const std::string& config_path, const std::string& calib_path,
                     const SettingsFile& config, const std::optional<SettingsFile>& calib,
                     Settings* settings) {
  if (!calib) {
    settings->calib_path = config_path;
    settings->calib = SensorCalib::load(config);
  } else {
    settings->calib_path = calib_path;
    settings->calib = SensorCalib::load(*calib);
    for (const std::string& key : calib->unreadKeys()) {
      log::warn(calib_path, ": unknown key ", key, " (ignored; a typo?)");
      settings->unknown_keys.push_back(calib_path + ": " + key);
    }
  }
}

// Every module's options from the config, then the whole-settings rule against the camera.
void loadModuleOptions(const SettingsFile& config, Settings* settings) {
  settings->orb = OrbOptions::load(config);
  settings->segmentation = SegmentationOptions::load(config);
  settings->keyframe = KeyFrameOptions::load(config);
  settings->tracking = TrackingOptions::load(config);
  settings->local_mapping = LocalMappingOptions::load(config);
  settings->loop = LoopOptions::load(config);
  settings->dense = DenseOptions::load(config);
  settings->imu_init = ImuInitOptions::load(config);
  settings->recon = ReconOptions::load(config);
  settings->viewer = ViewerOptions::load(config);
  settings->sequence = SequenceOptions::load(config);
  checkDenseAgainstCamera(settings->dense, settings->calib.camera.camera,
                          "Camera.width/height of " + settings->calib_path,
                          [&](const std::string& key, const std::string& value,
                              const std::string& expected) { config.fail(key, value, expected); });
}

// An override must name a key some setting read, and not a retired one.
void checkOverridesWereRead(const std::string& config_path,
                            const std::vector<SettingOverride>& overrides,
                            const SettingsFile& config, const std::optional<SettingsFile>& calib) {
  for (const SettingOverride& o : overrides) {
    if (const RetiredKey* retired = retiredKey(o.key)) {
      throw ConfigError(config_path + " (--set): " + o.key + " = " + o.value + ": the key is no longer used (" +
                        retired->note + ")");
    }
    if (!config.wasRead(o.key) && !(calib && calib->wasRead(o.key))) {
      throw ConfigError(config_path + " (--set): unknown key " + o.key + " = " + o.value +
                        ", expected a key of the settings (config_yaml/*.yaml lists them)");
    }
  }
}

// Unread keys of the config: calibration keys (with a calibration file) in one info line, retired
// keys with their note, the rest warned about as typos and listed in unknown_keys.
void reportUnreadConfigKeys(const std::string& config_path, const std::string& calib_path,
                            const SettingsFile& config, Settings* settings) {
  bool ignored_calibration = false;
  for (const std::string& key : config.unreadKeys()) {
    if (!calib_path.empty() && isCalibrationKey(key)) {
      ignored_calibration = true;  // expected: configs may carry a default calibration
      continue;
    }
    if (const RetiredKey* retired = retiredKey(key)) {
      log::warn(config_path, ": ", key, " is no longer used (ignored; ", retired->note, ")");
      continue;
    }
    log::warn(config_path, ": unknown key ", key, " (ignored; a typo?)");
    settings->unknown_keys.push_back(config_path + ": " + key);
  }
  if (ignored_calibration) {
    log::info(config_path, ": Camera.*/DepthMapFactor/IMU.* keys ignored; calibration from ",
              calib_path);
  }
}

}  // namespace

Settings Settings::load(const std::string& config_path, const std::string& calib_path,
                        const std::vector<SettingOverride>& overrides) {
  SettingsFile config(config_path);
  std::optional<SettingsFile> calib;
  if (!calib_path.empty()) calib.emplace(calib_path);
  applyOverrides(overrides, &config, &calib);
  Settings settings;
  settings.config_path = config_path;
  settings.overrides = overrides;
  loadCalibration(config_path, calib_path, config, calib, &settings);
  loadModuleOptions(config, &settings);
  checkOverridesWereRead(config_path, overrides, config, calib);
  reportUnreadConfigKeys(config_path, calib_path, config, &settings);
  return settings;
}

void Settings::validate() const {
  Validator validator;
  visitOrb(orb, validator);
  visitSegmentation(segmentation, validator);
  visitKeyFrame(keyframe, validator);
  visitTracking(tracking, validator);
  visitLocalMapping(local_mapping, validator);
  visitLoop(loop, validator);
  visitDense(dense, validator);
  visitImuInit(imu_init, validator);
  visitRecon(recon, validator);
  visitViewer(viewer, validator);
  checkDenseAgainstCamera(
      dense, calib.camera.camera, "camera calibration",
      [&](const std::string& key, const std::string& value, const std::string& expected) {
        validator.fail(key, value, expected);
      });
}

std::string Settings::describe() const {
  Describer d;
  d.os << "settings = " << config_path << "\n";
  for (const SettingOverride& o : overrides) d.os << "--set " << o.key << " = " << o.value << "\n";
  d.os << "calibration = " << calib_path << "\n";
  const PinholeCamera& cam = calib.camera.camera;
  d.os << "Camera.fx = " << cam.fx() << "\nCamera.fy = " << cam.fy() << "\nCamera.cx = " << cam.cx()
       << "\nCamera.cy = " << cam.cy() << "\nCamera.width = " << cam.width()
       << "\nCamera.height = " << cam.height() << "\nCamera.fps = " << calib.camera.fps
       << "\nDepthMapFactor = " << calib.camera.depth_map_factor << "\n";
  d.os << "Camera.lens = " << calib.camera.lens.describe() << "\n";
  if (calib.has_imu) {
    const SE3& T = calib.imu.T_b_c;
    const Quat& q = T.quaternion();
    d.os << "IMU.T_b_c1 = t [" << T.translation().transpose() << "] m, q (x y z w) [" << q.x()
         << " " << q.y() << " " << q.z() << " " << q.w() << "]\n";
    d.os << "IMU.NoiseGyro = " << calib.imu.noise_gyro << "\nIMU.NoiseAcc = " << calib.imu.noise_acc
         << "\nIMU.GyroWalk = " << calib.imu.gyro_walk << "\nIMU.AccWalk = " << calib.imu.acc_walk
         << "\nIMU.Frequency = " << calib.imu.rate_hz << "\nIMU.TimeOffset = " << calib.imu.time_offset_s << "\n";
  } else {
    d.os << "IMU = none\n";
  }
  visitOrb(orb, d);
  visitSegmentation(segmentation, d);
  visitKeyFrame(keyframe, d);
  visitTracking(tracking, d);
  visitLocalMapping(local_mapping, d);
  visitLoop(loop, d);
  visitDense(dense, d);
  visitImuInit(imu_init, d);
  visitRecon(recon, d);
  visitViewer(viewer, d);
  d.os << "Sequence.MaxImuGap = " << sequence.max_imu_gap_s << "\n";
  d.os << "Sequence.MaxImuReorder = " << sequence.max_imu_reorder_s << "\n";
  d.os << "Sequence.ImuGapPolicy = "
       << (sequence.imu_gap_policy == ImuGapPolicy::kFail ? "fail" : "warn") << "\n";
  std::string text = d.os.str();
  if (!text.empty()) text.pop_back();  // no trailing newline
  return text;
}

void Settings::log() const {
  std::istringstream lines(describe());
  std::string line;
  while (std::getline(lines, line)) log::info("settings: ", line);
}

}  // namespace ltlo
