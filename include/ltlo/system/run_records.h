#pragma once
/// Plain records of a run's results (System produces them, run_outputs.h writes them).
#include <cstdint>
#include <limits>
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/core/timing.h"
#include "ltlo/map/ids.h"
#include "ltlo/mapping/mapping_timeline.h"

namespace ltlo::system {

/// Camera pose of one input frame, from its reference keyframe's latest pose (so loop corrections
/// and merges after the frame was tracked move it along).
struct FramePose {
  double t_s = 0.0;
  SE3 T_w_c;
  bool tracked = false;  ///< tracked against the map (false: predicted while lost)
  map::MapId map;        ///< map of the reference keyframe now (after merges)
};

/// One keyframe of the Atlas at the time of the query.
struct KeyFrameRecord {
  double t_s = 0.0;
  SE3 T_w_c;
  std::uint64_t id = 0;
  std::uint64_t map = 0;
  double static_area_ratio = 1.0;
};

/// One map point for static_map.ply.
struct MapPointRecord {
  Vec3 p_w = Vec3::Zero();
  std::uint8_t red = 128, green = 128, blue = 128;  ///< sampled in the reference keyframe's image
  double beta = 1.0;                                ///< static score
  /// centres of the keyframes that observe the point (world; empty when unknown, e.g. read back from
  /// a PLY): each saw free space from its centre to the point
  std::vector<Vec3> observer_centres_w;
};

struct SystemCounts {
  int frames = 0;             ///< frames given to trackFrame
  int frames_with_pose = 0;   ///< frames with a pose (all after the first initialisation; before it, the
                              ///< dead-reckoned ones)
  int frames_tracked = 0;     ///< frames tracked against the map
  int maps = 0;               ///< maps of the Atlas holding content (Atlas::numMaps)
  int maps_created = 0;       ///< maps started after tracking loss
  /// frames tracked with fewer than Tracking.MinInliers pose inliers, carried by the inertial
  /// optimisation (Tracking.MinInliersImu)
  int frames_tracked_weak_imu = 0;
  int frames_imu_predicted = 0;  ///< untracked frames that got the IMU-only prediction
  /// frames posed by the IMU's dead reckoning while the view was too poor to start the first map
  /// (Tracking.PreMapImuPose)
  int frames_before_map = 0;
  int relocalisations = 0;       ///< frames relocalised against the keyframe database
  int maps_extended = 0;         ///< keyframes placed at the IMU prediction while lost
  int reacquisitions = 0;        ///< lost frames that re-acquired the map by the IMU-guided search
  int loops = 0;              ///< same-map loops corrected
  int merges = 0;             ///< maps merged
  int keyframes = 0;          ///< keyframes of all maps
  /// Culled keyframes the run's frame records hold as stand-ins without image data (RunRecorder::
  /// releaseCulledKeyFrames), and those they still hold whole (culled since the last release).
  int keyframes_released = 0;
  int keyframes_culled_held = 0;
  int map_points = 0;         ///< map points of all maps
  bool imu_initialised = false;
  /// A run in a loaded atlas (SystemOptions::load_atlas_path): its keyframes and points at load,
  /// and the time of the run's first pose (relocalised in it, or a new map; NaN: none).
  bool atlas_loaded = false;
  int keyframes_loaded = 0;
  int map_points_loaded = 0;
  /// Frames the loaded map's points localised (Tracking.LocalisationOnly; not carried by the visual
  /// odometry on temporary points or by the IMU alone).
  int frames_localised_in_map = 0;
  double first_pose_t_s = std::numeric_limits<double>::quiet_NaN();
};

/// Everything a run produced, gathered once after System::shutdown().
struct RunReport {
  std::vector<FramePose> trajectory;
  /// System::onlineTrajectory: every frame's pose as tracking returned it (trajectory_online.txt).
  std::vector<FramePose> trajectory_online;
  std::vector<KeyFrameRecord> keyframes;
  std::vector<MapPointRecord> map_points;
  map::MapId map_points_map;  ///< the map of map_points (the active one at the end)
  SystemCounts counts;
  std::vector<StageTiming> timing;
  std::vector<mapping::MappingTimelineEntry> mapping_timeline;  ///< mapping_timeline.csv
  double wall_s = 0.0;          ///< whole run (reading + SLAM), s
  double peak_memory_mb = 0.0;  ///< peak resident set size, MB
  bool interrupted = false;     ///< stopped early (signal or error)
  /// rgbd_inertial --rate (core/frame_pacer.h): the sequence played at this many times its recorded
  /// speed (0: as fast as tracking went), the frames that started more than a frame interval late and
  /// the lag of the frames behind the times they were due.
  double pacing_rate = 0.0;
  long paced_late_frames = 0;
  double paced_lag_mean_ms = 0.0;
  double paced_lag_max_ms = 0.0;
  /// the --oracle-masks ablation: ground-truth masks replaced the segmentation (diagnostic run)
  bool oracle_masks = false;
  /// The camera-IMU time offset at the end (LocalMapping.EstimateTimeOffset): IMU.TimeOffset plus
  /// the online estimate (t_imu = t_cam + offset), its sigma and the number of accepted estimates.
  bool time_offset_estimated = false;
  double time_offset_s = 0.0;
  double time_offset_sigma_s = 0.0;
  int time_offset_updates = 0;
  /// The live viewer (SystemOptions::viewer_*): pictures rendered, frames dropped because the
  /// viewer was behind, pictures written to each output, poses on the pose stream.
  bool viewer_on = false;
  std::uint64_t viewer_rendered = 0;
  std::uint64_t viewer_dropped = 0;
  std::uint64_t viewer_video_frames = 0;
  std::uint64_t viewer_video_held = 0;  ///< of the video frames, repeats for dropped states
  std::uint64_t viewer_png_frames = 0;
  std::uint64_t viewer_http_frames = 0;
  std::uint64_t viewer_poses = 0;
};

}  // namespace ltlo::system
