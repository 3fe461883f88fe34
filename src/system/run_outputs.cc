#include "ltlo/system/run_outputs.h"


#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <optional>
#include <sstream>
#include <utility>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/eval/mask_iou.h"
#include "ltlo/eval/trajectory_metrics.h"

namespace ltlo::system {
namespace {

constexpr const char* kKeyFramesHeader = "# t tx ty tz qx qy qz qw id map static_area_ratio";
constexpr const char* kMappingTimelineHeader =
    "# t keyframe_id mapping_ms atlas_keyframes atlas_map_points resident_mb ba_optimised ba_fixed ba_points "
    "ba_observations ba_fixed_observations ba_fixed_observation_limit ba_probe_points ba_iterations points_ms ba_ms keyframe_culling_ms imu_ms mapping_cpu_ms";
constexpr const char* kPlyVertexLayout[] = {"property float x",     "property float y",
                                            "property float z",     "property uchar red",
                                            "property uchar green", "property uchar blue",
                                            "property float beta"};
constexpr std::size_t kPlyVertexBytes = 3 * 4 + 3 + 4;

bool hostIsLittleEndian() {
  const std::uint16_t probe = 1;
  unsigned char first = 0;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

template <typename T>
void appendLittleEndian(std::string* bytes, T value) {
  char raw[sizeof(T)];
  std::memcpy(raw, &value, sizeof(T));
  if (!hostIsLittleEndian()) std::reverse(raw, raw + sizeof(T));
  bytes->append(raw, sizeof(T));
}

template <typename T>
T readLittleEndian(const char* raw) {
  char copy[sizeof(T)];
  std::memcpy(copy, raw, sizeof(T));
  if (!hostIsLittleEndian()) std::reverse(copy, copy + sizeof(T));
  T value;
  std::memcpy(&value, copy, sizeof(T));
  return value;
}

/// "tracking.frame" -> "tracking_frame" (flat metric keys).
std::string metricKey(std::string stage) {
  std::replace(stage.begin(), stage.end(), '.', '_');
  return stage;
}

}  // namespace

io::Trajectory toTumTrajectory(const std::vector<FramePose>& trajectory) {
  io::Trajectory tum;
  tum.reserve(trajectory.size());
  for (const FramePose& pose : trajectory) tum.push_back({pose.t_s, pose.T_w_c});
  return tum;
}

void writeTrajectory(const std::string& path, const std::vector<FramePose>& trajectory) {
  io::writeTumTrajectory(path, toTumTrajectory(trajectory));
}

void writeKeyFrames(const std::string& path, const std::vector<KeyFrameRecord>& keyframes) {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  out << kKeyFramesHeader << '\n';
  for (const KeyFrameRecord& kf : keyframes) {
    const Quat& q = kf.T_w_c.quaternion();
    const Vec3& t = kf.T_w_c.translation();
    out << std::fixed << std::setprecision(9) << kf.t_s << std::defaultfloat << std::setprecision(17) << ' '
        << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w()
        << ' ' << kf.id << ' ' << kf.map << ' ' << kf.static_area_ratio << '\n';
  }
  if (!out) throw InputError(path, 0, "write failed");
}

void writeMappingTimeline(const std::string& path, const std::vector<mapping::MappingTimelineEntry>& timeline) {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  out << kMappingTimelineHeader << '\n';
  for (const mapping::MappingTimelineEntry& entry : timeline) {
    out << std::fixed << std::setprecision(6) << entry.t_s << ' ' << entry.keyframe_id << ' ' << std::setprecision(3)
        << entry.mapping_ms << ' ' << entry.atlas_keyframes << ' ' << entry.atlas_map_points << ' '
        << std::setprecision(1) << entry.resident_mb << ' ' << entry.ba_optimised_keyframes << ' '
        << entry.ba_fixed_keyframes << ' ' << entry.ba_points << ' ' << entry.ba_observations << ' '
        << entry.ba_fixed_observations << ' ' << entry.ba_fixed_observation_limit << ' ' << entry.ba_probe_points << ' '
        << entry.ba_iterations << ' ' << std::setprecision(3)
        << entry.points_ms << ' ' << entry.ba_ms << ' ' << entry.keyframe_culling_ms << ' ' << entry.imu_ms << ' '
        << entry.mapping_cpu_ms << '\n';
  }
  if (!out) throw InputError(path, 0, "write failed");
}

MappingTimelineSummary summariseMappingTimeline(const std::vector<mapping::MappingTimelineEntry>& timeline,
                                                double window_s) {
  MappingTimelineSummary summary;
  if (timeline.empty()) return summary;
  double first_t_s = timeline.front().t_s, last_t_s = timeline.front().t_s;
  for (const mapping::MappingTimelineEntry& entry : timeline) {
    first_t_s = std::min(first_t_s, entry.t_s);
    last_t_s = std::max(last_t_s, entry.t_s);
    summary.max_resident_mb = std::max(summary.max_resident_mb, entry.resident_mb);
  }
  // The two windows must not overlap, or the ratio would compare a stretch with itself.
  if (last_t_s - first_t_s < 2.0 * window_s) return summary;
  std::vector<double> first_ms, last_ms, first_cpu_ms, last_cpu_ms;
  // Local BA sizes of the keyframes that ran one: observations, points, fixed keyframes.
  std::vector<double> first_ba[3], last_ba[3];
  auto add_ba = [](const mapping::MappingTimelineEntry& entry, std::vector<double>* sizes) {
    if (entry.ba_observations <= 0) return;
    sizes[0].push_back(entry.ba_observations);
    sizes[1].push_back(entry.ba_points);
    sizes[2].push_back(entry.ba_fixed_keyframes);
  };
  for (const mapping::MappingTimelineEntry& entry : timeline) {
    if (entry.t_s < first_t_s + window_s) {
      first_ms.push_back(entry.mapping_ms);
      first_cpu_ms.push_back(entry.mapping_cpu_ms);
      add_ba(entry, first_ba);
    }
    if (entry.t_s > last_t_s - window_s) {
      last_ms.push_back(entry.mapping_ms);
      last_cpu_ms.push_back(entry.mapping_cpu_ms);
      add_ba(entry, last_ba);
      summary.last_resident_mb = std::max(summary.last_resident_mb, entry.resident_mb);
    } else if (entry.t_s < first_t_s + window_s) {
      summary.first_resident_mb = std::max(summary.first_resident_mb, entry.resident_mb);
    }
  }
  summary.windows = true;
  summary.first_median_ms = percentile(first_ms, 0.5);
  summary.last_median_ms = percentile(last_ms, 0.5);
  summary.first_median_cpu_ms = percentile(first_cpu_ms, 0.5);
  summary.last_median_cpu_ms = percentile(last_cpu_ms, 0.5);
  auto median = [](std::vector<double>& values) { return values.empty() ? 0.0 : percentile(values, 0.5); };
  summary.first_ba_observations = median(first_ba[0]);
  summary.last_ba_observations = median(last_ba[0]);
  summary.first_ba_points = median(first_ba[1]);
  summary.last_ba_points = median(last_ba[1]);
  summary.first_ba_fixed_keyframes = median(first_ba[2]);
  summary.last_ba_fixed_keyframes = median(last_ba[2]);
  return summary;
}

std::vector<KeyFrameRecord> readKeyFrames(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open");
  std::vector<KeyFrameRecord> keyframes;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double t_s = 0.0, tx = 0.0, ty = 0.0, tz = 0.0, qx = 0.0, qy = 0.0, qz = 0.0, qw = 0.0, ratio = 0.0;
    std::uint64_t id = 0, map = 0;
    std::string extra;
    if (!(fields >> t_s >> tx >> ty >> tz >> qx >> qy >> qz >> qw >> id >> map >> ratio) || (fields >> extra)) {
      throw InputError(path, line_number, "expected 't tx ty tz qx qy qz qw id map static_area_ratio', got '" +
                                              line + "'");
    }
    const Quat q(qw, qx, qy, qz);
    if (!std::isfinite(q.norm()) || std::abs(q.norm() - 1.0) > 1e-6) {
      throw InputError(path, line_number, "quaternion is not unit (norm " + std::to_string(q.norm()) + ")");
    }
    KeyFrameRecord kf;
    kf.t_s = t_s;
    kf.T_w_c = SE3(q, Vec3(tx, ty, tz));
    kf.id = id;
    kf.map = map;
    kf.static_area_ratio = ratio;
    keyframes.push_back(kf);
  }
  return keyframes;
}

int writeStaticMapPly(const std::string& path, const std::vector<MapPointRecord>& points, double min_beta) {
  std::string body;
  int count = 0;
  for (const MapPointRecord& point : points) {
    if (point.beta < min_beta) continue;
    for (int k = 0; k < 3; ++k) appendLittleEndian(&body, static_cast<float>(point.p_w[k]));
    body.push_back(static_cast<char>(point.red));
    body.push_back(static_cast<char>(point.green));
    body.push_back(static_cast<char>(point.blue));
    appendLittleEndian(&body, static_cast<float>(point.beta));
    ++count;
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  out << "ply\nformat binary_little_endian 1.0\n"
      << "comment LTLO-SLAM static map points (world frame of the active map, m), beta = static score\n"
      << "element vertex " << count << '\n';
  for (const char* property : kPlyVertexLayout) out << property << '\n';
  out << "end_header\n";
  out.write(body.data(), static_cast<std::streamsize>(body.size()));
  if (!out) throw InputError(path, 0, "write failed");
  return count;
}

std::vector<MapPointRecord> readStaticMapPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open");
  std::string line;
  int line_number = 0;
  long count = -1;
  std::size_t property = 0;
  auto next = [&]() -> bool {
    if (!std::getline(in, line)) return false;
    ++line_number;
    return true;
  };
  if (!next() || line != "ply") throw InputError(path, 1, "not a PLY file (first line '" + line + "')");
  if (!next() || line != "format binary_little_endian 1.0") {
    throw InputError(path, line_number, "expected 'format binary_little_endian 1.0', got '" + line + "'");
  }
  while (next() && line != "end_header") {
    if (line.rfind("comment", 0) == 0) continue;
    if (line.rfind("element vertex ", 0) == 0) {
      const std::string count_text = line.substr(15);
      char* end = nullptr;
      errno = 0;
      const long long parsed = std::strtoll(count_text.c_str(), &end, 10);
      if (count >= 0 || count_text.empty() || *end != '\0' || errno == ERANGE || parsed < 0 ||
          parsed > std::numeric_limits<long>::max() / static_cast<long>(kPlyVertexBytes)) {
        throw InputError(path, line_number, "bad or repeated vertex count '" + count_text + "'");
      }
      count = static_cast<long>(parsed);
      continue;
    }
    if (property >= std::size(kPlyVertexLayout) || line != kPlyVertexLayout[property]) {
      throw InputError(path, line_number, "unexpected header line '" + line + "'");
    }
    ++property;
  }
  if (line != "end_header") throw InputError(path, line_number, "no end_header");
  if (count < 0 || property != std::size(kPlyVertexLayout)) {
    throw InputError(path, line_number, "header lacks the vertex element or its properties");
  }
  // The announced count must fit in the file before anything is allocated for it.
  const std::streamoff body_begin = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff body_bytes = in.tellg() - body_begin;
  in.seekg(body_begin);
  if (body_begin < 0 || body_bytes < static_cast<std::streamoff>(count) * static_cast<std::streamoff>(kPlyVertexBytes)) {
    throw InputError(path, 0,
                     "truncated: " + std::to_string(count) + " vertices announced, " +
                         std::to_string(std::max<std::streamoff>(body_bytes, 0)) + " bytes of vertex data");
  }
  std::string body(static_cast<std::size_t>(count) * kPlyVertexBytes, '\0');
  in.read(body.data(), static_cast<std::streamsize>(body.size()));
  if (in.gcount() != static_cast<std::streamsize>(body.size())) {
    throw InputError(path, 0, "truncated: " + std::to_string(count) + " vertices announced");
  }
  std::vector<MapPointRecord> points(static_cast<std::size_t>(count));
  for (std::size_t i = 0; i < points.size(); ++i) {
    const char* raw = body.data() + i * kPlyVertexBytes;
    MapPointRecord& point = points[i];
    for (int k = 0; k < 3; ++k) point.p_w[k] = readLittleEndian<float>(raw + 4 * k);
    point.red = static_cast<std::uint8_t>(raw[12]);
    point.green = static_cast<std::uint8_t>(raw[13]);
    point.blue = static_cast<std::uint8_t>(raw[14]);
    point.beta = readLittleEndian<float>(raw + 15);
  }
  return points;
}

namespace {

/// ATE (SE3 alignment) and RPE of `trajectory` against `ground_truth` under keys "<prefix>_...":
/// prefix "ate"/"rpe" give ate_rmse_m, rpe_trans_rmse_m_s, ...; `suffix` names the matched count.
void addTrajectoryErrors(const std::vector<FramePose>& trajectory, const io::Trajectory& ground_truth,
                         const std::string& ate_prefix, const std::string& rpe_prefix,
                         const std::string& matched_key, io::Metrics* metrics) {
  const eval::MatchedTrajectories matched = eval::associateTrajectories(ground_truth, toTumTrajectory(trajectory));
  metrics->set(matched_key, static_cast<int>(matched.est.size()));
  if (matched.est.size() < 3) {
    log::warn("metrics: only ", matched.est.size(), " poses of the ", ate_prefix == "ate" ? "" : "online ",
              "trajectory match the ground truth; no ", ate_prefix, "/", rpe_prefix);
    return;
  }
  const eval::AteResult ate = eval::computeAte(matched, /*with_scale=*/false);
  const eval::RpeResult rpe = eval::computeRpe(matched, ate.S_gt_est);
  metrics->set(ate_prefix + "_rmse_m", ate.error_m.rmse);
  metrics->set(ate_prefix + "_mean_m", ate.error_m.mean);
  metrics->set(ate_prefix + "_median_m", ate.error_m.median);
  metrics->set(ate_prefix + "_max_m", ate.error_m.max);
  metrics->set(rpe_prefix + "_trans_rmse_m_s", rpe.trans_m_s.rmse);
  metrics->set(rpe_prefix + "_rot_rmse_deg_s", rpe.rot_deg_s.rmse);
  metrics->set(rpe_prefix + "_trans_rmse_m_frame", rpe.trans_m_frame.rmse);
  metrics->set(rpe_prefix + "_rot_rmse_deg_frame", rpe.rot_deg_frame.rmse);
}

}  // namespace

io::Metrics computeRunMetrics(const RunReport& report, const io::Trajectory& ground_truth) {
  io::Metrics metrics;
  if (!ground_truth.empty()) {
    addTrajectoryErrors(report.trajectory, ground_truth, "ate", "rpe", "num_matched", &metrics);
    // The online stream (trajectory_online.txt): the same figures of the poses as tracking
    // returned them, so the live pose's quality is known beside the final one.
    addTrajectoryErrors(report.trajectory_online, ground_truth, "ate_online", "rpe_online", "num_matched_online",
                        &metrics);
  }
  const SystemCounts& c = report.counts;
  metrics.set("frames", c.frames);
  metrics.set("frames_with_pose", c.frames_with_pose);
  metrics.set("frames_tracked", c.frames_tracked);
  metrics.set("frames_without_pose", c.frames - c.frames_with_pose);
  metrics.set("interrupted", report.interrupted ? 1 : 0);
  metrics.setFlag("oracle_masks", report.oracle_masks);
  metrics.set("imu_initialised", c.imu_initialised ? 1 : 0);
  metrics.set("maps", c.maps);
  metrics.set("maps_created", c.maps_created);
  metrics.set("frames_tracked_weak_imu", c.frames_tracked_weak_imu);
  metrics.set("frames_imu_predicted", c.frames_imu_predicted);
  metrics.set("frames_before_map", c.frames_before_map);
  metrics.set("relocalisations", c.relocalisations);
  metrics.set("maps_extended", c.maps_extended);
  metrics.set("reacquisitions", c.reacquisitions);
  metrics.set("loops", c.loops);
  metrics.set("merges", c.merges);
  metrics.set("keyframes", c.keyframes);
  metrics.set("map_points", c.map_points);
  if (c.atlas_loaded) {
    // A run in a loaded atlas: what it found there and what it added.
    metrics.set("atlas_loaded", 1);
    metrics.set("keyframes_loaded", c.keyframes_loaded);
    metrics.set("keyframes_added", c.keyframes - c.keyframes_loaded);
    metrics.set("map_points_loaded", c.map_points_loaded);
    metrics.set("localised_share", c.frames > 0 ? static_cast<double>(c.frames_tracked) / c.frames : 0.0);
    if (c.frames_localised_in_map > 0) {
      // Localisation only: by the map's points (the rest carried by the odometry or the IMU).
      metrics.set("map_localised_share", c.frames > 0 ? static_cast<double>(c.frames_localised_in_map) / c.frames : 0.0);
    }
    if (std::isfinite(c.first_pose_t_s)) metrics.set("first_pose_t_s", c.first_pose_t_s);
  }
  metrics.set("wall_s", report.wall_s);
  metrics.set("fps", report.wall_s > 0.0 ? c.frames / report.wall_s : 0.0);
  metrics.set("peak_memory_mb", report.peak_memory_mb);
  if (report.pacing_rate > 0.0) {
    // Played at the camera's pace (--rate): did tracking keep up?
    metrics.set("rate", report.pacing_rate);
    metrics.set("late_frames", static_cast<int64_t>(report.paced_late_frames));
    metrics.set("late_frame_share", c.frames > 0 ? static_cast<double>(report.paced_late_frames) / c.frames : 0.0);
    metrics.set("lag_mean_ms", report.paced_lag_mean_ms);
    metrics.set("lag_max_ms", report.paced_lag_max_ms);
  }
  // Long runs: does the mapping cost per keyframe (and the memory) stay bounded?
  const MappingTimelineSummary timeline = summariseMappingTimeline(report.mapping_timeline, 60.0);
  if (timeline.windows) {
    metrics.set("mapping_keyframe_first_minute_median_ms", timeline.first_median_ms);
    metrics.set("mapping_keyframe_last_minute_median_ms", timeline.last_median_ms);
    metrics.set("mapping_keyframe_last_to_first_minute",
                timeline.first_median_ms > 0.0 ? timeline.last_median_ms / timeline.first_median_ms : 0.0);
    metrics.set("mapping_keyframe_cpu_first_minute_median_ms", timeline.first_median_cpu_ms);
    metrics.set("mapping_keyframe_cpu_last_minute_median_ms", timeline.last_median_cpu_ms);
    metrics.set("mapping_keyframe_cpu_last_to_first_minute",
                timeline.first_median_cpu_ms > 0.0 ? timeline.last_median_cpu_ms / timeline.first_median_cpu_ms : 0.0);
    metrics.set("resident_first_minute_max_mb", timeline.first_resident_mb);
    metrics.set("resident_last_minute_max_mb", timeline.last_resident_mb);
    metrics.set("local_ba_first_minute_median_observations", timeline.first_ba_observations);
    metrics.set("local_ba_last_minute_median_observations", timeline.last_ba_observations);
    metrics.set("local_ba_first_minute_median_points", timeline.first_ba_points);
    metrics.set("local_ba_last_minute_median_points", timeline.last_ba_points);
    metrics.set("local_ba_first_minute_median_fixed_keyframes", timeline.first_ba_fixed_keyframes);
    metrics.set("local_ba_last_minute_median_fixed_keyframes", timeline.last_ba_fixed_keyframes);
  }
  if (report.time_offset_estimated) {
    metrics.set("imu_time_offset_s", report.time_offset_s);
    metrics.set("imu_time_offset_sigma_s", report.time_offset_sigma_s);
    metrics.set("imu_time_offset_updates", report.time_offset_updates);
  }
  if (report.viewer_on) {
    metrics.set("viewer_rendered", static_cast<int64_t>(report.viewer_rendered));
    metrics.set("viewer_dropped", static_cast<int64_t>(report.viewer_dropped));
    metrics.set("viewer_video_frames", static_cast<int64_t>(report.viewer_video_frames));
    metrics.set("viewer_video_held", static_cast<int64_t>(report.viewer_video_held));
    metrics.set("viewer_png_frames", static_cast<int64_t>(report.viewer_png_frames));
    metrics.set("viewer_http_frames", static_cast<int64_t>(report.viewer_http_frames));
    metrics.set("viewer_poses", static_cast<int64_t>(report.viewer_poses));
  }
  for (const StageTiming& stage : report.timing) {
    const std::string key = metricKey(stage.stage);
    metrics.set(key + "_count", static_cast<int64_t>(stage.count));
    metrics.set(key + "_median_ms", 1e3 * stage.median_s);
    metrics.set(key + "_p95_ms", 1e3 * stage.p95_s);
    metrics.set(key + "_max_ms", 1e3 * stage.max_s);
  }
  return metrics;
}

namespace {

/// trajectory.txt, keyframes.txt and static_map.ply: the run's own outputs, written before any
/// evaluation input is opened.
WrittenOutputs writeSlamOutputs(const std::string& out_dir, const RunReport& report, double min_beta) {
  namespace fs = std::filesystem;
  std::error_code error;
  fs::create_directories(out_dir, error);
  if (error) throw InputError(out_dir, 0, "cannot create the output folder: " + error.message());
  WrittenOutputs written;
  const std::string trajectory_path = (fs::path(out_dir) / "trajectory.txt").string();
  writeTrajectory(trajectory_path, report.trajectory);
  written.files.push_back(trajectory_path);
  const std::string online_path = (fs::path(out_dir) / "trajectory_online.txt").string();
  writeTrajectory(online_path, report.trajectory_online);
  written.files.push_back(online_path);
  const std::string keyframes_path = (fs::path(out_dir) / "keyframes.txt").string();
  writeKeyFrames(keyframes_path, report.keyframes);
  written.files.push_back(keyframes_path);
  const std::string timeline_path = (fs::path(out_dir) / "mapping_timeline.txt").string();
  writeMappingTimeline(timeline_path, report.mapping_timeline);
  written.files.push_back(timeline_path);
  const std::string ply_path = (fs::path(out_dir) / "static_map.ply").string();
  written.static_points = writeStaticMapPly(ply_path, report.map_points, min_beta);
  written.files.push_back(ply_path);
  return written;
}

void addEvaluationError(WrittenOutputs* written, const std::string& message) {
  log::error("metrics: evaluation failed: ", message);
  if (!written->evaluation_error.empty()) written->evaluation_error += "; ";
  written->evaluation_error += message;
}

/// The metrics step: ATE/RPE against `ground_truth`, the mask figures against `gt_masks_dir`, and
/// metrics.json, written when there is ground truth or an evaluation error (`ground_truth_error`:
/// groundtruth.txt could not be read). A malformed mask folder becomes an evaluation error too.
void writeMetrics(const std::string& out_dir, const RunReport& report, const io::Trajectory& ground_truth,
                  const std::string& ground_truth_error, const std::string& gt_masks_dir, WrittenOutputs* written) {
  namespace fs = std::filesystem;
  if (ground_truth.empty() && ground_truth_error.empty()) return;
  if (!ground_truth_error.empty()) addEvaluationError(written, ground_truth_error);
  io::Metrics figures = computeRunMetrics(report, ground_truth);
  // The same figures as `evaluate --gt-masks SEQ/masks --est-masks RUN/<folder>`; none when the run wrote
  // no masks there (Ctrl-C before the first frame, Seg.HindsightMasks 0): nothing to compare, not an error.
  const auto maskFigures = [&](const char* folder) -> std::optional<eval::MaskIouResult> {
    std::error_code error;
    const fs::path masks_dir = fs::path(out_dir) / folder;
    if (gt_masks_dir.empty() || !fs::is_directory(gt_masks_dir, error) || !fs::is_directory(masks_dir, error) ||
        fs::is_empty(masks_dir, error)) {
      return std::nullopt;
    }
    try {
      return eval::evaluateMaskFolders(gt_masks_dir, masks_dir.string());
    } catch (const InputError& e) {
      addEvaluationError(written, e.what());
      return std::nullopt;
    }
  };
  if (const std::optional<eval::MaskIouResult> iou = maskFigures("segmentation")) {
    figures.set("static_iou", iou->mean_static_iou);
    figures.set("static_iou_occluded", iou->mean_static_iou_occluded);
    figures.set("num_mask_frames", iou->num_frames);
    figures.set("num_occluded_frames", iou->num_occluded_frames);
    figures.set("dynamic_recall", iou->dynamic_recall);
    figures.set("static_share", iou->mean_static_share);
  }
  // The hindsight masks, when the run wrote them.
  if (const std::optional<eval::MaskIouResult> iou = maskFigures("segmentation_final")) {
    figures.set("static_iou_final", iou->mean_static_iou);
    figures.set("static_iou_occluded_final", iou->mean_static_iou_occluded);
    figures.set("dynamic_recall_final", iou->dynamic_recall);
  }
  if (!written->evaluation_error.empty()) figures.set("evaluation_error", written->evaluation_error);
  written->metrics = std::move(figures);
  written->has_metrics = true;
  const std::string metrics_path = (fs::path(out_dir) / "metrics.json").string();
  written->metrics.writeJson(metrics_path);
  written->files.push_back(metrics_path);
}

}  // namespace

WrittenOutputs writeRunOutputs(const std::string& out_dir, const RunReport& report,
                               const io::Trajectory& ground_truth, double min_beta, const std::string& gt_masks_dir) {
  WrittenOutputs written = writeSlamOutputs(out_dir, report, min_beta);
  writeMetrics(out_dir, report, ground_truth, "", gt_masks_dir, &written);
  return written;
}

WrittenOutputs writeRunOutputs(const std::string& out_dir, const RunReport& report,
                               const EvaluationInputs& evaluation, double min_beta) {
  WrittenOutputs written = writeSlamOutputs(out_dir, report, min_beta);
  io::Trajectory ground_truth;
  std::string ground_truth_error;
  if (!evaluation.ground_truth_path.empty()) {
    try {
      ground_truth = io::readTumTrajectory(evaluation.ground_truth_path);
      log::info("metrics: ", evaluation.ground_truth_path, ": ", ground_truth.size(), " ground-truth poses");
    } catch (const InputError& e) {
      ground_truth_error = e.what();
    }
  }
  writeMetrics(out_dir, report, ground_truth, ground_truth_error, evaluation.gt_masks_dir, &written);
  return written;
}

}  // namespace ltlo::system
