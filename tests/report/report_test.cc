// The benchmark report on a generated benchmark folder (one sequence, one run with a known ATE and
// IoU), its flat-JSON reader and the plot ticks.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "ltlo/core/errors.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/report/benchmark_report.h"
#include "ltlo/report/flat_json.h"
#include "ltlo/report/plot.h"

namespace ltlo::report {
namespace {

namespace fs = std::filesystem;

std::string readAll(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

TEST(FlatJson, ReadsNumbersStringsAndNulls) {
  const FlatJson json = FlatJson::parse(
      "{\n  \"ate_rmse_m\": 0.0125,\n  \"frames\": 1350,\n  \"name\": \"run \\\"a\\\"\",\n"
      "  \"static_iou\": null,\n  \"ok\": true\n}\n",
      "m.json");
  EXPECT_DOUBLE_EQ(*json.number("ate_rmse_m"), 0.0125);
  EXPECT_DOUBLE_EQ(*json.number("frames"), 1350.0);
  EXPECT_EQ(*json.text("name"), "run \"a\"");
  EXPECT_FALSE(json.number("static_iou").has_value());
  EXPECT_DOUBLE_EQ(*json.number("ok"), 1.0);
  EXPECT_FALSE(json.has("missing"));
  try {
    FlatJson::parse("{\n\"a\": 1,\n\"b\": {\"c\": 2}\n}", "nested.json");
    ADD_FAILURE() << "nested object accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nested.json:3: nested value under \"b\""),
              std::string::npos)
        << e.what();
  }
}

TEST(Plot, TicksAreRoundNumbersCoveringTheRange) {
  const std::vector<double> ticks = niceTicks(0.0, 0.047);
  ASSERT_GE(ticks.size(), 4u);
  EXPECT_NEAR(ticks[1] - ticks[0], 0.01, 1e-12);
  EXPECT_NEAR(ticks.back(), 0.04, 1e-12);
  const std::vector<double> wide = niceTicks(-3.2, 4.1);
  EXPECT_NEAR(wide[1] - wide[0], 2.0, 1e-12);
  EXPECT_NEAR(wide.front(), -2.0, 1e-12);
}

// A benchmark folder: a 40-frame sequence (circle of radius 2 m, 10 Hz, frames 10-19 half
// dynamic) and one run whose trajectory is the ground truth shifted by a constant 1 m (removed by
// the alignment) plus +-2 cm alternating in z (ATE 2 cm), with a segmentation that marks the
// dynamic half of frames 10-19 and nothing else (IoU 1 on all frames but 15, where it is empty:
// IoU 0.5).
class BenchmarkFolder : public ::testing::Test {
 protected:
  BenchmarkFolder()
      : dir_((fs::temp_directory_path() / ("report_" + std::to_string(::getpid()))).string()) {
    const std::string seq = dir_ + "/seq/ltlo_s7";
    const std::string run = dir_ + "/runs/ltlo_s7/rgbd_inertial";
    fs::create_directories(seq + "/masks");
    fs::create_directories(run + "/segmentation");
    io::Trajectory gt, est;
    for (int k = 0; k < 40; ++k) {
      const double t = 0.1 * k, a = 0.15 * k;
      const Vec3 p(2 * std::cos(a), 2 * std::sin(a), 0.5);
      gt.push_back({t, SE3(Quat::Identity(), p)});
      est.push_back({t, SE3(Quat::Identity(), p + Vec3(1, 0, k % 2 ? 0.02 : -0.02))});
      cv::Mat mask(12, 16, CV_8UC1, cv::Scalar(0));
      if (k >= 10 && k < 20) mask(cv::Rect(0, 0, 16, 6)).setTo(255);
      const std::string name = cv::format("%.6f.png", t);
      cv::imwrite(seq + "/masks/" + name, mask);
      if (k == 15) mask.setTo(0);  // a missed detection: static IoU 96 / 192 = 0.5
      cv::imwrite(run + "/segmentation/" + name, mask);
    }
    io::writeTumTrajectory(seq + "/groundtruth.txt", gt);
    io::writeTumTrajectory(run + "/trajectory.txt", est);
    std::ofstream(run + "/sequence_path.txt") << seq << "\n";
    std::ofstream(run + "/metrics.json")
        << "{\"ate_rmse_m\": 0.02, \"ate_online_rmse_m\": 0.05, \"rpe_trans_rmse_m_s\": 0.4, "
           "\"rpe_rot_rmse_deg_s\": 0.0, "
           "\"fps\": 28.5, \"tracking_frame_median_ms\": 21.0, \"tracking_frame_p95_ms\": 30.0, "
           "\"mapping_local_ba_median_ms\": 120.0, \"mapping_local_ba_p95_ms\": 300.0, "
           "\"peak_memory_mb\": 512, \"maps\": 1, \"loops\": 2, \"merges\": 0, \"wall_s\": 4.2}";
  }
  ~BenchmarkFolder() override { fs::remove_all(dir_); }
  std::string dir_;
};

TEST_F(BenchmarkFolder, RunSeriesHaveTheKnownErrorsAndIou) {
  const std::vector<RunRecord> runs = findRuns(dir_);
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].scenario, "ltlo");
  EXPECT_EQ(runs[0].seed, 7);
  EXPECT_EQ(runs[0].variant, "rgbd_inertial");
  const RunSeries series = loadSeries(runs[0], dir_ + "/cache");
  ASSERT_EQ(series.t_s.size(), 40u);
  EXPECT_NEAR(series.ate_rmse_m, 0.02, 1e-6);
  ASSERT_EQ(series.dynamic_share.size(), 40u);
  EXPECT_NEAR(series.dynamic_share[12], 0.5, 1e-12);
  EXPECT_NEAR(series.dynamic_share[25], 0.0, 1e-12);
  ASSERT_EQ(series.iou.size(), 40u);
  EXPECT_NEAR(series.mean_iou, (39.0 + 0.5) / 40.0, 1e-9);
  EXPECT_NEAR(series.mean_iou_occluded, (9.0 + 0.5) / 10.0, 1e-9);
  EXPECT_TRUE(fs::is_regular_file(dir_ + "/cache/ltlo_s7_dynamic.txt"));
}

// A folder that is not a benchmark output, or a run whose sequence moved, is bad input naming the
// file (the report would silently lack ATE and IoU).
TEST_F(BenchmarkFolder, MissingRunsFolderOrSequenceIsAnInputErrorNamingIt) {
  const auto message = [](const std::string& dir) -> std::string {
    try {
      writeBenchmarkReport(dir, "x");
    } catch (const InputError& e) {
      return e.what();
    }
    return "accepted";
  };
  EXPECT_EQ(message(dir_ + "/seq"),
            dir_ + "/seq: no runs/ folder (not a scripts/benchmark.sh output folder)");
  const std::string path = dir_ + "/runs/ltlo_s7/rgbd_inertial/sequence_path.txt";
  std::ofstream(path) << dir_ << "/moved\n";
  EXPECT_EQ(message(dir_), path + ":1: sequence folder '" + dir_ + "/moved' does not exist");
}

TEST_F(BenchmarkFolder, ReportHasTheTablesAndThePlot) {
  EXPECT_EQ(writeBenchmarkReport(dir_, "test report"), 1);
  const std::string md = readAll(dir_ + "/report.md");
  EXPECT_NE(md.find("test report"), std::string::npos);
  // Summary and per-run rows: ATE from the alignment, the online ATE of metrics.json, IoU all /
  // occluded, FPS, memory, loops.
  EXPECT_NE(md.find("| ltlo | rgbd_inertial | 1 | 0.020 | 0.050 | 0.400 | 0.00 | 0.988 | 0.950 | 28.5 | "
                    "21.0 | 512 | 1.0 | 2.0 |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| ltlo_s7 | rgbd_inertial | 0.020 | 0.050 | 0.400 |"), std::string::npos) << md;
  EXPECT_NE(md.find("![ltlo_s7 rgbd_inertial](plots/ltlo_s7_rgbd_inertial.png)"),
            std::string::npos);
  const cv::Mat plot = cv::imread(dir_ + "/plots/ltlo_s7_rgbd_inertial.png");
  ASSERT_FALSE(plot.empty());
  EXPECT_EQ(plot.cols, 1600);
  EXPECT_EQ(plot.rows, 1000);
  // The top view draws the estimate in red (BGR 40, 60, 220) and the occluded stretch in orange.
  const cv::Mat top = plot(cv::Rect(0, 0, 800, 500));
  cv::Mat red, orange;
  cv::inRange(top, cv::Scalar(30, 50, 200), cv::Scalar(60, 80, 240), red);
  cv::inRange(top, cv::Scalar(0, 140, 245), cv::Scalar(10, 160, 255), orange);
  EXPECT_GT(cv::countNonZero(red), 500);
  EXPECT_GT(cv::countNonZero(orange), 500);
  // Only the five occlusion profiles: no harder-worlds section; not paced: no real-time section.
  EXPECT_EQ(md.find("## Harder worlds"), std::string::npos);
  EXPECT_EQ(md.find("## Real time"), std::string::npos);
}

// A run played at the camera's pace (--rate) gets a row in the real-time section: its late frames and lag.
TEST_F(BenchmarkFolder, PacedRunsGetARealTimeSection) {
  std::ofstream(dir_ + "/runs/ltlo_s7/rgbd_inertial/metrics.json", std::ios::trunc)
      << "{\"ate_rmse_m\": 0.02, \"fps\": 10.0, \"tracking_frame_median_ms\": 21.0, \"tracking_frame_p95_ms\": 30.0, "
         "\"rate\": 1, \"late_frames\": 3, \"late_frame_share\": 0.075, \"lag_mean_ms\": 4.3, \"lag_max_ms\": 61.5, "
         "\"wall_s\": 4.2}";
  EXPECT_EQ(writeBenchmarkReport(dir_, "test report"), 1);
  const std::string md = readAll(dir_ + "/report.md");
  const std::size_t section = md.find("## Real time");
  ASSERT_NE(section, std::string::npos) << md;
  const std::size_t row = md.find("| ltlo_s7 | rgbd_inertial | 1 | 3 | 0.075 | 4.3 | 61.5 | 21.0 | 30.0 |", section);
  EXPECT_NE(row, std::string::npos) << md;
}

// A run of a scenario beyond the occlusion profiles gets a row in the harder-worlds section, with
// its dynamic recall and the long-run mapping ratio from metrics.json.
TEST_F(BenchmarkFolder, HarderWorldScenariosGetTheirOwnSection) {
  const std::string run = dir_ + "/runs/plain_ltlo_s7/rgbd_inertial";
  fs::create_directories(run);
  fs::copy(dir_ + "/runs/ltlo_s7/rgbd_inertial", run, fs::copy_options::recursive);
  std::ofstream(run + "/metrics.json", std::ios::trunc)
      << "{\"ate_rmse_m\": 0.02, \"ate_online_rmse_m\": 0.05, \"frames_without_pose\": 3, \"maps\": 1, "
         "\"loops\": 2, \"merges\": 1, \"dynamic_recall\": 0.9125, \"peak_memory_mb\": 640, "
         "\"mapping_keyframe_last_to_first_minute\": 1.234, \"mapping_keyframe_cpu_last_to_first_minute\": 1.106, \"keyframes\": 321, \"wall_s\": 4.2}";
  std::ofstream(run + "/check_loops.txt") << "loop closed kf9(t=3.0) ~ kf1(t=0.3): true distance 0.10 m\n"
                                          << "FALSE maps merged kf20(t=6.0) ~ kf2(t=0.6): true distance 1.00 m\n";
  EXPECT_EQ(writeBenchmarkReport(dir_, "test report"), 2);
  const std::string md = readAll(dir_ + "/report.md");
  const std::size_t section = md.find("## Harder worlds");
  ASSERT_NE(section, std::string::npos) << md;
  const std::size_t row = md.find("| plain_ltlo_s7 | rgbd_inertial | 0.020 | 0.050 | 3 | 1 | 0.988 | 0.912 | 2 | 1 | 1 | 321 | 640 | 1.23 | 1.11 |");
  EXPECT_NE(row, std::string::npos) << md;
  EXPECT_GT(row, section);
  // The profile's run stays out of the section.
  EXPECT_EQ(md.find("| ltlo_s7 | rgbd_inertial |", section), std::string::npos);
}

}  // namespace
}  // namespace ltlo::report
