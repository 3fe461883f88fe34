#include "stage_options.h"

#include <algorithm>
#include <utility>

#include "ltlo/core/undistorter.h"
#include "ltlo/tracking/dense_segmenter.h"
#include "ltlo/tracking/oracle_mask_segmenter.h"

namespace ltlo::system {

tracking::TrackerOptions trackerOptions(const Settings& settings, bool use_imu) {
  tracking::TrackerOptions tracker_options;
  tracker_options.keyframe = settings.keyframe;
  tracker_options.tracking = settings.tracking;
  tracker_options.imu_init = settings.imu_init;
  // Localisation only: a lost frame waits for the loaded map (relocalised, re-acquired, or carried by
  // the IMU); it never extends the map or starts a new one.
  if (settings.tracking.localisation_only) tracker_options.tracking.new_map_after_s = -1.0;
  if (use_imu && settings.imu_init.early_keyframes) {
    tracker_options.imu_init_keyframe_interval_s =
        settings.imu_init.min_time_s / std::max(1, settings.imu_init.min_keyframes - 1);
  }
  const TrackingOptions& tracking = settings.tracking;
  // Without the IMU there is nothing to keep a pose before the first map with.
  tracker_options.tracking.pre_map_imu_pose = use_imu && tracking.pre_map_imu_pose;
  // The rest before the first map is the dead reckoning's.
  tracker_options.imu_init.from_pre_map_rest =
      tracker_options.tracking.pre_map_imu_pose && settings.imu_init.from_pre_map_rest;
  tracker_options.zero_velocity_test =
      use_imu && (tracking.zupt || tracking.zupt_no_keyframes || settings.imu_init.from_rest);
  tracker_options.zero_velocity =
      imu::ZeroVelocityOptions::fromCalib(settings.calib.imu, tracking.zupt_window_s, tracking.zupt_threshold);
  tracker_options.rest_keyframe = use_imu && settings.imu_init.from_rest;
  tracker_options.rest_time_s = settings.imu_init.rest_time_s;
  return tracker_options;
}

mapping::LocalMapperOptions localMapperOptions(const Settings& settings, const SensorCalib& calib,
                                               std::shared_ptr<const bow::Vocabulary> vocabulary, bool use_imu) {
  mapping::LocalMapperOptions mapper_options;
  mapper_options.local_mapping = settings.local_mapping;
  mapper_options.segmentation = settings.segmentation;
  mapper_options.vocabulary = std::move(vocabulary);
  mapper_options.imu_init = settings.imu_init;
  mapper_options.use_imu = use_imu;
  mapper_options.refine_until_acceleration_sigma_m_s2 = settings.tracking.acc_bias_sigma_m_s2;
  // Every RGB-D edge (tracking, local BA, fusion, loop and global BA): bf = fx * virtual baseline.
  mapper_options.bf_px_m = calib.camera.camera.fx() * settings.tracking.virtual_baseline_m;
  return mapper_options;
}

loop::LoopCloserOptions loopCloserOptions(const Settings& settings, const tracking::TrackerOptions& tracker_options,
                                          bool use_imu) {
  loop::LoopCloserOptions closer_options;
  closer_options.loop = settings.loop;
  closer_options.loop.wait_for_imu = use_imu && settings.loop.wait_for_imu;
  closer_options.rejoin_search = tracking::reacquireSearchOptions(tracker_options);
  closer_options.virtual_baseline_m = settings.tracking.virtual_baseline_m;
  closer_options.min_point_beta = settings.local_mapping.min_point_beta;
  closer_options.lambda_imu = settings.local_mapping.lambda_imu;
  closer_options.visual_variance_estimation = settings.local_mapping.visual_variance_estimation;
  return closer_options;
}

std::unique_ptr<tracking::FrameSegmenter> makeSegmenter(const Settings& settings, bool oracle_masks, TimingStats* timing,
                                                        const std::shared_ptr<const Undistorter>& undistorter) {
  const SegmentationOptions& seg = settings.segmentation;
  if (oracle_masks) return std::make_unique<tracking::OracleMaskSegmenter>(seg.static_threshold, undistorter);
  if (!seg.enable) return std::make_unique<tracking::AllStaticSegmenter>(seg.static_threshold);
  if (seg.dense_init) {
    return std::make_unique<tracking::DenseSegmenter>(seg, settings.dense, settings.local_mapping,
                                                      settings.calib.camera.camera, timing, undistorter);
  }
  return std::make_unique<tracking::ClusterOnlySegmenter>(seg, settings.dense, settings.calib.camera.camera, timing,
                                                          undistorter);
}

}  // namespace ltlo::system
