// Run outputs (issue 6): trajectory.txt, keyframes.txt and static_map.ply round-trip their
// writers, the PLY keeps only points with beta >= the threshold, metrics.json carries ATE against
// ground truth and the run's counts and timing, and bad files are rejected with the file named.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "ltlo/core/errors.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/system/run_outputs.h"
#include "ltlo/system/segmentation_writer.h"

namespace ltlo::system {
namespace {

namespace fs = std::filesystem;

class RunOutputs : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ltlo_run_outputs_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

SE3 randomPose(std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  return SE3(so3ExpQuat(Vec3(normal(rng), normal(rng), normal(rng))), Vec3(normal(rng), normal(rng), normal(rng)));
}

TEST_F(RunOutputs, KeyFramesRoundTrip) {
  std::mt19937 rng(3);
  std::vector<KeyFrameRecord> keyframes;
  for (int i = 0; i < 20; ++i) {
    KeyFrameRecord kf;
    kf.t_s = 1.0 + 0.1 * i;
    kf.T_w_c = randomPose(rng);
    kf.id = static_cast<std::uint64_t>(3 * i + 1);
    kf.map = static_cast<std::uint64_t>(i / 7);
    kf.static_area_ratio = 0.05 * i;
    keyframes.push_back(kf);
  }
  writeKeyFrames(path("keyframes.txt"), keyframes);
  std::ifstream in(path("keyframes.txt"));
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "# t tx ty tz qx qy qz qw id map static_area_ratio");

  const std::vector<KeyFrameRecord> read = readKeyFrames(path("keyframes.txt"));
  ASSERT_EQ(read.size(), keyframes.size());
  for (std::size_t i = 0; i < read.size(); ++i) {
    EXPECT_NEAR(read[i].t_s, keyframes[i].t_s, 1e-9);
    EXPECT_LT((read[i].T_w_c.translation() - keyframes[i].T_w_c.translation()).norm(), 1e-12);
    EXPECT_LT(read[i].T_w_c.quaternion().angularDistance(keyframes[i].T_w_c.quaternion()), 1e-12);
    EXPECT_EQ(read[i].id, keyframes[i].id);
    EXPECT_EQ(read[i].map, keyframes[i].map);
    EXPECT_DOUBLE_EQ(read[i].static_area_ratio, keyframes[i].static_area_ratio);
  }
}

TEST_F(RunOutputs, KeyFramesReaderNamesTheBadLine) {
  {
    std::ofstream out(path("bad.txt"));
    out << "# t tx ty tz qx qy qz qw id map static_area_ratio\n";
    out << "1.0 0 0 0 0 0 0 1 4 0 1.0\n";
    out << "1.1 0 0 0 0 0 0 1 five 0 1.0\n";
  }
  try {
    readKeyFrames(path("bad.txt"));
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.txt:3:"), std::string::npos) << e.what();
  }
}

TEST_F(RunOutputs, StaticMapPlyRoundTripKeepsStaticPointsOnly) {
  std::vector<MapPointRecord> points;
  for (int i = 0; i < 50; ++i) {
    MapPointRecord point;
    point.p_w = Vec3(0.25 * i, -0.5 * i, 1.0 + 0.125 * i);  // exact in float
    point.red = static_cast<std::uint8_t>(5 * i);
    point.green = static_cast<std::uint8_t>(255 - 5 * i);
    point.blue = static_cast<std::uint8_t>(i);
    point.beta = (i % 5 == 0) ? 0.25 : 0.75;  // every fifth point dynamic
    points.push_back(point);
  }
  EXPECT_EQ(writeStaticMapPly(path("map.ply"), points, 0.5), 40);
  const std::vector<MapPointRecord> read = readStaticMapPly(path("map.ply"));
  ASSERT_EQ(read.size(), 40u);
  std::size_t k = 0;
  for (const MapPointRecord& point : points) {
    if (point.beta < 0.5) continue;
    EXPECT_EQ(read[k].p_w, point.p_w);
    EXPECT_EQ(read[k].red, point.red);
    EXPECT_EQ(read[k].green, point.green);
    EXPECT_EQ(read[k].blue, point.blue);
    EXPECT_DOUBLE_EQ(read[k].beta, point.beta);
    ++k;
  }
  // An ASCII header is readable by any PLY viewer; the first line says what it is.
  std::ifstream in(path("map.ply"));
  std::string first, second;
  std::getline(in, first);
  std::getline(in, second);
  EXPECT_EQ(first, "ply");
  EXPECT_EQ(second, "format binary_little_endian 1.0");
}

TEST_F(RunOutputs, TruncatedPlyIsRejected) {
  std::vector<MapPointRecord> points(3);
  writeStaticMapPly(path("map.ply"), points, 0.0);
  fs::resize_file(path("map.ply"), fs::file_size(path("map.ply")) - 5);
  EXPECT_THROW(readStaticMapPly(path("map.ply")), InputError);
}

/// A run report whose trajectory is the ground truth moved by a fixed offset plus a known error
/// on every other frame.
RunReport syntheticReport(const io::Trajectory& ground_truth, double error_m) {
  RunReport report;
  const SE3 T_est_gt(so3ExpQuat(Vec3(0.0, 0.0, 0.3)), Vec3(1.0, 2.0, 0.5));
  for (std::size_t i = 0; i < ground_truth.size(); ++i) {
    FramePose pose;
    pose.t_s = ground_truth[i].t_s;
    const Vec3 error = (i % 2 == 0 ? 1.0 : -1.0) * error_m * Vec3::UnitX();
    pose.T_w_c = T_est_gt * SE3(ground_truth[i].T_w_x.quaternion(), ground_truth[i].T_w_x.translation() + error);
    pose.tracked = true;
    report.trajectory.push_back(pose);
    // The online stream: the same frames, 3 cm off along y (what tracking returned before a loop).
    FramePose online = pose;
    online.T_w_c = T_est_gt * SE3(ground_truth[i].T_w_x.quaternion(),
                                  ground_truth[i].T_w_x.translation() + error + (i % 2 == 0 ? 0.03 : -0.03) * Vec3::UnitY());
    report.trajectory_online.push_back(online);
  }
  report.counts.frames = static_cast<int>(ground_truth.size()) + 2;
  report.counts.frames_with_pose = static_cast<int>(ground_truth.size());
  report.counts.frames_tracked = static_cast<int>(ground_truth.size()) - 1;
  report.counts.maps = 1;
  report.counts.loops = 2;
  report.counts.keyframes = 7;
  report.counts.map_points = 900;
  report.timing = {StageTiming{"tracking.frame", 10, 0.2, 0.02, 0.018, 0.03, 0.04}};
  report.wall_s = 2.0;
  report.peak_memory_mb = 123.0;
  return report;
}

io::Trajectory circleGroundTruth(int n) {
  io::Trajectory gt;
  for (int i = 0; i < n; ++i) {
    const double a = 0.1 * i;
    gt.push_back({0.1 * i, SE3(so3ExpQuat(Vec3(0.0, 0.0, a)), Vec3(std::cos(a), std::sin(a), 0.1 * std::sin(3 * a)))});
  }
  return gt;
}

TEST_F(RunOutputs, MetricsCarryAteCountsAndTiming) {
  const io::Trajectory gt = circleGroundTruth(40);
  const RunReport report = syntheticReport(gt, 0.01);
  const io::Metrics metrics = computeRunMetrics(report, gt);
  // Alternating +-1 cm along one axis: after the best rigid alignment the rmse stays ~1 cm.
  EXPECT_NEAR(metrics.number("ate_rmse_m"), 0.01, 1e-3);
  EXPECT_NEAR(metrics.number("ate_max_m"), 0.01, 2e-3);
  EXPECT_EQ(metrics.number("num_matched"), 40);
  // The online stream's figures beside the final ones: +-1 cm along x and +-3 cm along y.
  EXPECT_EQ(metrics.number("num_matched_online"), 40);
  EXPECT_NEAR(metrics.number("ate_online_rmse_m"), std::sqrt(0.01 * 0.01 + 0.03 * 0.03), 2e-3);
  EXPECT_TRUE(metrics.has("rpe_online_trans_rmse_m_s"));
  EXPECT_EQ(metrics.number("frames"), 42);
  EXPECT_EQ(metrics.number("frames_with_pose"), 40);
  EXPECT_EQ(metrics.number("frames_without_pose"), 2);
  EXPECT_EQ(metrics.number("frames_tracked"), 39);
  EXPECT_EQ(metrics.number("loops"), 2);
  EXPECT_EQ(metrics.number("keyframes"), 7);
  EXPECT_EQ(metrics.number("map_points"), 900);
  EXPECT_NEAR(metrics.number("fps"), 21.0, 1e-12);
  EXPECT_NEAR(metrics.number("tracking_frame_median_ms"), 18.0, 1e-9);
  EXPECT_NEAR(metrics.number("tracking_frame_p95_ms"), 30.0, 1e-9);
  EXPECT_NEAR(metrics.number("peak_memory_mb"), 123.0, 1e-12);
  EXPECT_FALSE(metrics.has("late_frames"));  // not paced
}

TEST_F(RunOutputs, APacedRunCarriesItsLateFramesAndLag) {
  const io::Trajectory gt = circleGroundTruth(40);
  RunReport report = syntheticReport(gt, 0.01);
  report.pacing_rate = 1.0;
  report.paced_late_frames = 21;
  report.paced_lag_mean_ms = 2.5;
  report.paced_lag_max_ms = 80.0;
  const io::Metrics metrics = computeRunMetrics(report, gt);
  EXPECT_EQ(metrics.number("rate"), 1.0);
  EXPECT_EQ(metrics.number("late_frames"), 21);
  EXPECT_NEAR(metrics.number("late_frame_share"), 21.0 / 42.0, 1e-12);
  EXPECT_EQ(metrics.number("lag_mean_ms"), 2.5);
  EXPECT_EQ(metrics.number("lag_max_ms"), 80.0);
}

// A 5-minute timeline whose mapping cost doubles over the run: the first and last minutes' medians
// and their ratio; a run shorter than two minutes has no windows (they would overlap).
TEST_F(RunOutputs, MappingTimelineGivesTheFirstAndLastMinutesCostAndIsWritten) {
  std::vector<mapping::MappingTimelineEntry> timeline;
  for (int k = 0; k <= 600; ++k) {  // two keyframes a second over 300 s
    mapping::MappingTimelineEntry entry;
    entry.t_s = 0.5 * k;
    entry.keyframe_id = static_cast<std::uint64_t>(k);
    entry.mapping_ms = 100.0 + entry.t_s / 3.0 + (k % 2 == 0 ? 5.0 : -5.0);  // 100 ms -> 200 ms
    entry.atlas_keyframes = static_cast<std::size_t>(k + 1);
    entry.resident_mb = 200.0 + entry.t_s;
    // Local BA on every keyframe but one in ten: observations 1000 -> 1600 over the run.
    if (k % 10 != 5) {
      entry.ba_optimised_keyframes = 10;
      entry.ba_fixed_keyframes = 20 + k / 20;
      entry.ba_points = 500;
      entry.ba_observations = 1000 + k;
      entry.ba_fixed_observations = 600 + k;
      entry.ba_fixed_observation_limit = k > 300 ? 4 : 0;
      entry.ba_probe_points = 300 + k;
      entry.ba_iterations = 7;
    }
    entry.points_ms = 2.0 + 0.01 * k;
    entry.ba_ms = 0.8 * entry.mapping_ms;
    entry.keyframe_culling_ms = 0.5;
    entry.imu_ms = 1.25;
    entry.mapping_cpu_ms = 50.0 + entry.t_s / 10.0;  // 50 ms -> 80 ms: the thread's own work
    timeline.push_back(entry);
  }
  const MappingTimelineSummary summary = summariseMappingTimeline(timeline, 60.0);
  ASSERT_TRUE(summary.windows);
  // First minute: t in [0, 60), median at t = 29.75 s; last: t in (240, 300], median at 270.25 s.
  EXPECT_NEAR(summary.first_median_ms, 100.0 + 29.75 / 3.0, 5.01);
  EXPECT_NEAR(summary.last_median_ms, 100.0 + 270.25 / 3.0, 5.01);
  EXPECT_NEAR(summary.first_median_cpu_ms, 50.0 + 29.75 / 10.0, 1e-9);
  EXPECT_NEAR(summary.last_median_cpu_ms, 50.0 + 270.25 / 10.0, 1e-9);
  EXPECT_NEAR(summary.first_resident_mb, 259.5, 1e-9);
  EXPECT_NEAR(summary.last_resident_mb, 500.0, 1e-9);
  EXPECT_NEAR(summary.max_resident_mb, 500.0, 1e-9);
  // The BA sizes' medians over the keyframes that ran one: k in [0, 119] and [481, 600] but
  // those ending in 5, medians at k = 59.5 and 540.5.
  EXPECT_NEAR(summary.first_ba_observations, 1059.5, 1.01);
  EXPECT_NEAR(summary.last_ba_observations, 1540.5, 1.01);
  EXPECT_NEAR(summary.first_ba_points, 500.0, 1e-9);
  EXPECT_NEAR(summary.first_ba_fixed_keyframes, 23.0, 1.01);
  EXPECT_NEAR(summary.last_ba_fixed_keyframes, 47.0, 1.01);

  const std::vector<mapping::MappingTimelineEntry> short_run(timeline.begin(), timeline.begin() + 200);
  EXPECT_FALSE(summariseMappingTimeline(short_run, 60.0).windows);

  RunReport report = syntheticReport(circleGroundTruth(10), 0.0);
  report.mapping_timeline = timeline;
  const io::Metrics metrics = computeRunMetrics(report, circleGroundTruth(10));
  EXPECT_NEAR(metrics.number("mapping_keyframe_last_to_first_minute"),
              summary.last_median_ms / summary.first_median_ms, 1e-12);
  EXPECT_NEAR(metrics.number("mapping_keyframe_cpu_last_to_first_minute"), 77.025 / 52.975, 1e-12);
  EXPECT_NEAR(metrics.number("local_ba_first_minute_median_observations"), summary.first_ba_observations, 1e-12);
  EXPECT_NEAR(metrics.number("local_ba_last_minute_median_observations"), summary.last_ba_observations, 1e-12);
  writeMappingTimeline(path("timeline.txt"), timeline);
  std::ifstream in(path("timeline.txt"));
  std::string header, line;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("# t keyframe_id mapping_ms", 0), 0u);
  {
    std::istringstream names(header);
    std::string name;
    int columns = -1;  // the leading '#'
    while (names >> name) ++columns;
    EXPECT_EQ(columns, 19) << header;
    EXPECT_NE(header.find("ba_probe_points ba_iterations points_ms ba_ms keyframe_culling_ms imu_ms mapping_cpu_ms"), std::string::npos);
  }
  int lines = 0;
  double t_s = 0.0, mapping_ms = 0.0, resident_mb = 0.0;
  std::uint64_t id = 0, keyframes = 0, points = 0;
  int ba_optimised = 0, ba_fixed = 0, ba_points = 0, ba_observations = 0, ba_fixed_observations = 0;
  int ba_fixed_limit = -1, ba_probes = 0, ba_iterations = 0;
  double points_ms = 0.0, ba_ms = 0.0, culling_ms = 0.0, imu_ms = 0.0, cpu_ms = 0.0;
  std::string rest;
  while (std::getline(in, line)) {
    std::istringstream row(line);
    row >> t_s >> id >> mapping_ms >> keyframes >> points >> resident_mb >> ba_optimised >> ba_fixed >> ba_points >>
        ba_observations >> ba_fixed_observations >> ba_fixed_limit >> ba_probes >> ba_iterations >> points_ms >> ba_ms >>
        culling_ms >> imu_ms >> cpu_ms;
    EXPECT_TRUE(row && !(row >> rest)) << line;  // every column, no more
    ++lines;
  }
  EXPECT_EQ(ba_probes, 900);
  EXPECT_EQ(ba_iterations, 7);
  EXPECT_NEAR(points_ms, 8.0, 1e-3);
  EXPECT_NEAR(ba_ms, 0.8 * timeline.back().mapping_ms, 1e-3);
  EXPECT_NEAR(culling_ms, 0.5, 1e-3);
  EXPECT_NEAR(imu_ms, 1.25, 1e-3);
  EXPECT_NEAR(cpu_ms, 80.0, 1e-3);
  EXPECT_EQ(ba_optimised, 10);
  EXPECT_EQ(ba_fixed, 50);
  EXPECT_EQ(ba_points, 500);
  EXPECT_EQ(ba_observations, 1600);
  EXPECT_EQ(ba_fixed_observations, 1200);
  EXPECT_EQ(ba_fixed_limit, 4);
  EXPECT_EQ(lines, 601);
  EXPECT_NEAR(t_s, 300.0, 1e-9);
  EXPECT_EQ(id, 600u);
  EXPECT_EQ(keyframes, 601u);
  EXPECT_NEAR(mapping_ms, timeline.back().mapping_ms, 1e-3);
  EXPECT_NEAR(resident_mb, 500.0, 0.05);
}

TEST_F(RunOutputs, WriteRunOutputsWritesEveryFileAndTheTrajectoryReadsBack) {
  const io::Trajectory gt = circleGroundTruth(30);
  RunReport report = syntheticReport(gt, 0.0);
  report.keyframes.push_back(KeyFrameRecord{0.0, SE3(), 0, 0, 1.0});
  report.map_points.resize(4);
  const WrittenOutputs written = writeRunOutputs(path("run"), report, gt, 0.5);
  ASSERT_EQ(written.files.size(), 6u);
  for (const std::string& file : written.files) EXPECT_TRUE(fs::is_regular_file(file)) << file;
  EXPECT_TRUE(written.has_metrics);
  const io::Trajectory online = io::readTumTrajectory(path("run/trajectory_online.txt"));
  ASSERT_EQ(online.size(), gt.size());
  EXPECT_LT((online[5].T_w_x.translation() - report.trajectory_online[5].T_w_c.translation()).norm(), 1e-12);
  EXPECT_GT((online[5].T_w_x.translation() - report.trajectory[5].T_w_c.translation()).norm(), 0.02);
  EXPECT_LT(written.metrics.number("ate_rmse_m"), 1e-9);
  EXPECT_EQ(written.static_points, 4);
  const io::Trajectory trajectory = io::readTumTrajectory(path("run/trajectory.txt"));
  ASSERT_EQ(trajectory.size(), gt.size());
  EXPECT_LT((trajectory[5].T_w_x.translation() - report.trajectory[5].T_w_c.translation()).norm(), 1e-12);

  // Without ground truth there is no metrics.json.
  const WrittenOutputs without = writeRunOutputs(path("run2"), report, io::Trajectory(), 0.5);
  EXPECT_EQ(without.files.size(), 5u);
  EXPECT_FALSE(fs::exists(path("run2/metrics.json")));
}

// SegmentationWriter: masks pushed at the label resolution come out as <name>.png at the input
// resolution (nearest upsampling, 0/255 kept), named like the sequence's masks/, written by the
// writer thread; writeRunOutputs then adds the IoU figures against a ground-truth masks/ folder.
TEST_F(RunOutputs, SegmentationMasksAreWrittenAndScoredAgainstTheGroundTruth) {
  EXPECT_EQ(SegmentationWriter::frameName("seq/rgb/1.033333.png", 1.0333333), "1.033333");
  EXPECT_EQ(SegmentationWriter::frameName("seq/rgb/frame_7.png", 2.5), "2.500000");
  fs::create_directories(path("gt"));
  {
    SegmentationWriter writer(path("run/segmentation"), 2);  // a small queue: push waits, never drops
    for (int i = 0; i < 5; ++i) {
      cv::Mat label_mask(3, 4, CV_8U, cv::Scalar(0));
      label_mask(cv::Rect(0, 0, 2, 3)) = 255;  // left half dynamic
      const std::string name = std::to_string(i) + ".000000";
      writer.push(name, label_mask, 8, 6);
      cv::Mat gt(6, 8, CV_8U, cv::Scalar(0));
      gt(cv::Rect(0, 0, i < 3 ? 4 : 2, 6)) = 255;  // frames 0-2: exactly the left half
      cv::imwrite(path("gt/" + name + ".png"), gt);
    }
    EXPECT_EQ(writer.finish(), 5);
  }
  const cv::Mat written = cv::imread(path("run/segmentation/3.000000.png"), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(written.type(), CV_8UC1);
  ASSERT_EQ(written.size(), cv::Size(8, 6));
  EXPECT_EQ(cv::countNonZero(written == 255), 24);
  EXPECT_EQ(cv::countNonZero(written == 0), 24);

  const io::Trajectory gt = circleGroundTruth(30);
  const WrittenOutputs outputs = writeRunOutputs(path("run"), syntheticReport(gt, 0.0), gt, 0.5, path("gt"));
  // Frames 0-2: IoU 1; frames 3-4: static gt 36 px, static estimate 24 px inside it: 24 / 36.
  EXPECT_NEAR(outputs.metrics.number("static_iou"), (3.0 + 2.0 * 24.0 / 36.0) / 5.0, 1e-12);
  EXPECT_NEAR(outputs.metrics.number("static_iou_occluded"), 1.0, 1e-12);  // frames 0-2: 50 % dynamic
  EXPECT_EQ(outputs.metrics.number("num_occluded_frames"), 3);
  EXPECT_EQ(outputs.metrics.number("num_mask_frames"), 5);
  EXPECT_NEAR(outputs.metrics.number("dynamic_recall"), 1.0, 1e-12);
  EXPECT_NEAR(outputs.metrics.number("static_share"), 0.5, 1e-12);
}

// The evaluation inputs are read at the metrics step, after the run's own files: a ground truth
// that does not parse throws nothing; metrics.json has the counts and "evaluation_error" naming
// file, line and value, and no ATE. A readable one gives the figures it gave when read up front.
TEST_F(RunOutputs, MalformedGroundTruthFileIsAnEvaluationErrorNotAnException) {
  const io::Trajectory gt = circleGroundTruth(30);
  const RunReport report = syntheticReport(gt, 0.0);
  io::writeTumTrajectory(path("gt.txt"), gt);
  EvaluationInputs evaluation;
  evaluation.ground_truth_path = path("gt.txt");
  const WrittenOutputs good = writeRunOutputs(path("run"), report, evaluation, 0.5);
  EXPECT_TRUE(good.evaluation_error.empty()) << good.evaluation_error;
  EXPECT_LT(good.metrics.number("ate_rmse_m"), 1e-9);
  // The same metrics as the ground truth read beforehand (what the SLAM programs did before).
  EXPECT_EQ(good.metrics.toJson(),
            writeRunOutputs(path("run_b"), report, io::readTumTrajectory(path("gt.txt")), 0.5).metrics.toJson());

  {
    std::ofstream out(path("bad.txt"));
    out << "# t tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n0.1 0 0 nope 0 0 0 1\n";
  }
  evaluation.ground_truth_path = path("bad.txt");
  WrittenOutputs bad;
  ASSERT_NO_THROW(bad = writeRunOutputs(path("run2"), report, evaluation, 0.5));
  ASSERT_EQ(bad.files.size(), 6u);  // trajectory, online, keyframes, mapping timeline, map, metrics
  for (const std::string& file : bad.files) EXPECT_TRUE(fs::is_regular_file(file)) << file;
  EXPECT_EQ(io::readTumTrajectory(path("run2/trajectory.txt")).size(), gt.size());
  EXPECT_EQ(bad.evaluation_error.rfind(path("bad.txt") + ":3: ", 0), 0u) << bad.evaluation_error;
  EXPECT_NE(bad.evaluation_error.find("nope"), std::string::npos) << bad.evaluation_error;
  EXPECT_TRUE(bad.has_metrics);
  EXPECT_FALSE(bad.metrics.has("ate_rmse_m"));
  EXPECT_EQ(bad.metrics.number("frames"), report.counts.frames);
  std::ifstream json(path("run2/metrics.json"));
  const std::string text((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"evaluation_error\": \"" + path("bad.txt") + ":3: "), std::string::npos) << text;

  // No ground-truth file: no metrics.json, no error.
  const WrittenOutputs none = writeRunOutputs(path("run3"), report, EvaluationInputs{}, 0.5);
  EXPECT_FALSE(none.has_metrics);
  EXPECT_TRUE(none.evaluation_error.empty());
  EXPECT_FALSE(fs::exists(path("run3/metrics.json")));
}

}  // namespace
}  // namespace ltlo::system
