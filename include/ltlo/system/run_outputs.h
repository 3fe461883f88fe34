#pragma once
/// The outputs of a run (DESIGN.md "Outputs of a run"), written from what System reports:
///   trajectory.txt   TUM "t tx ty tz qx qy qz qw", camera pose T_w_c, every frame with a pose,
///                    from its reference keyframe's final pose (loop corrections, merges and the
///                    smoothing of IMU-carried stretches included)
///   trajectory_online.txt  the same frames with the pose tracking returned at that frame (the
///                    online stream a controller reads; never corrected afterwards)
///   keyframes.txt    "# t tx ty tz qx qy qz qw id map static_area_ratio", T_w_c, by time
///   static_map.ply   binary little-endian PLY: float x y z, uchar red green blue, float beta
///                    (world frame of the active map, points with beta >= the threshold)
///   metrics.json     when ground truth is given: ATE / RPE (and ate_online_* / rpe_online_* of
///                    trajectory_online.txt, num_matched_online), frame counts, per-stage median/p95
///                    times, peak memory, wall time, FPS, maps, loops, merges, keyframes, points,
///                    and the static-background IoU of segmentation/ against the sequence's masks/;
///                    when an evaluation input is malformed, the figures that could be computed and
///                    "evaluation_error" (the reader's message: file, line, value)
///   segmentation/    every frame's mask (written during the run by SegmentationWriter)
///   segmentation_final/  the same masks relabelled after the run against the final map and poses
///                    (hindsight_masks.h, written by the program before these outputs; metrics.json's
///                    static_iou_final, static_iou_occluded_final, dynamic_recall_final)
/// Readers for keyframes.txt and static_map.ply round-trip the writers (tests, tools). Writers
/// and readers throw InputError naming the file (and line) on failure.
#include <string>
#include <vector>

#include "ltlo/io/metrics_json.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/system/run_records.h"

namespace ltlo::system {

void writeTrajectory(const std::string& path, const std::vector<FramePose>& trajectory);
/// The trajectory as TUM poses (T_w_c).
io::Trajectory toTumTrajectory(const std::vector<FramePose>& trajectory);

void writeKeyFrames(const std::string& path, const std::vector<KeyFrameRecord>& keyframes);
std::vector<KeyFrameRecord> readKeyFrames(const std::string& path);

/// mapping_timeline.txt: one line per processed keyframe (its time, id, mapping ms, the atlas's
/// keyframes and points after it, the resident memory MB), in processing order.
void writeMappingTimeline(const std::string& path, const std::vector<mapping::MappingTimelineEntry>& timeline);

/// The mapping cost of a run's first and last `window_s` of keyframe time (metrics.json's
/// mapping_keyframe_first/last_minute_median_ms): `windows` is false when the run is shorter than
/// two windows (they would overlap).
struct MappingTimelineSummary {
  bool windows = false;
  double first_median_ms = 0.0;
  double last_median_ms = 0.0;
  /// The same medians of the mapping thread's CPU time (its work, without the waits for the cores).
  double first_median_cpu_ms = 0.0;
  double last_median_cpu_ms = 0.0;
  double first_resident_mb = 0.0;  ///< the largest resident memory in each window, MB
  double last_resident_mb = 0.0;
  double max_resident_mb = 0.0;    ///< over the whole timeline
  /// Median local BA problem size of the keyframes that ran one, in each window (load-insensitive;
  /// issue 32): observations, points and fixed keyframes.
  double first_ba_observations = 0.0;
  double last_ba_observations = 0.0;
  double first_ba_points = 0.0;
  double last_ba_points = 0.0;
  double first_ba_fixed_keyframes = 0.0;
  double last_ba_fixed_keyframes = 0.0;
};
MappingTimelineSummary summariseMappingTimeline(const std::vector<mapping::MappingTimelineEntry>& timeline,
                                                double window_s);

/// Writes the points with beta >= min_beta; returns how many.
int writeStaticMapPly(const std::string& path, const std::vector<MapPointRecord>& points, double min_beta);
/// Reads a PLY written by writeStaticMapPly (exactly that vertex layout).
std::vector<MapPointRecord> readStaticMapPly(const std::string& path);

/// metrics.json values: ATE (SE3 alignment) and RPE of the trajectory against `ground_truth` when
/// it is not empty and at least 3 poses match, then counts, timing, memory, wall time and FPS.
io::Metrics computeRunMetrics(const RunReport& report, const io::Trajectory& ground_truth);

/// Files written by writeRunOutputs (paths) and the metrics (empty without ground truth).
struct WrittenOutputs {
  std::vector<std::string> files;
  io::Metrics metrics;
  bool has_metrics = false;
  int static_points = 0;
  /// Why the evaluation failed (a malformed groundtruth.txt or masks/: the InputError messages,
  /// "; "-separated; also metrics.json's "evaluation_error"); empty when it did not.
  std::string evaluation_error;
};

/// The evaluation inputs of a run (ground truth: never read before the run has ended, so a broken
/// file cannot stop or change the run).
struct EvaluationInputs {
  std::string ground_truth_path;  ///< TUM groundtruth.txt (T_w_c); empty: none (no metrics.json)
  std::string gt_masks_dir;       ///< the sequence's masks/; empty: no mask figures
};

/// Creates `out_dir` and writes trajectory.txt, keyframes.txt, static_map.ply and, with ground
/// truth, metrics.json. With `gt_masks_dir` (a sequence's masks/) and the run's segmentation/
/// folder (SystemOptions::segmentation_dir = out_dir/segmentation), metrics.json also gets the
/// segmentation figures of eval::evaluateMaskFolders: static_iou, static_iou_occluded,
/// num_mask_frames, num_occluded_frames, dynamic_recall, static_share. A malformed mask folder does
/// not throw: its message is WrittenOutputs::evaluation_error (logged, and in metrics.json).
WrittenOutputs writeRunOutputs(const std::string& out_dir, const RunReport& report,
                               const io::Trajectory& ground_truth, double min_beta,
                               const std::string& gt_masks_dir = "");

/// The same, reading the evaluation inputs only now, after the run's own outputs are written:
/// a ground-truth file that does not parse gives a metrics.json without ATE/RPE but with
/// "evaluation_error" naming the file, line and value (also WrittenOutputs::evaluation_error and one
/// error log line), never an exception. An existing but empty ground truth gives no metrics.json.
/// Throws InputError only when an output cannot be written.
WrittenOutputs writeRunOutputs(const std::string& out_dir, const RunReport& report,
                               const EvaluationInputs& evaluation, double min_beta);

}  // namespace ltlo::system
