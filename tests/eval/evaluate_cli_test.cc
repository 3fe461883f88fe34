// Runs the built evaluate program (path from CMake: LTLO_EVALUATE_BINARY) on generated files.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "ltlo/io/trajectory_io.h"
#include "test_sequence_writer.h"

namespace ltlo {
namespace {

namespace fs = std::filesystem;
using io::test::readText;
using io::test::TempDir;
using io::test::writeText;

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

RunResult runEvaluate(const TempDir& tmp, const std::string& args) {
  const std::string command = std::string(LTLO_EVALUATE_BINARY) + " " + args + " > " +
                              tmp.file("stdout.txt") + " 2> " + tmp.file("stderr.txt");
  const int status = std::system(command.c_str());
  RunResult result;
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = readText(tmp.file("stdout.txt"));
  result.err = readText(tmp.file("stderr.txt"));
  return result;
}

std::map<std::string, std::string> parseLines(const std::string& text) {
  std::map<std::string, std::string> values;
  std::istringstream in(text);
  std::string name, value;
  while (in >> name >> value) values[name] = value;
  return values;
}

// Ground truth on a circle at 10 Hz; the estimate is offset +-d alternately along z in pairs
// of equal positions (ATE RMSE = d after alignment, see the library tests).
void writeTrajectories(const TempDir& tmp, double d_m) {
  io::Trajectory gt, est;
  for (int k = 0; k < 40; ++k) {
    const double a = 0.2 * (k / 2);
    const Vec3 p(std::cos(a), std::sin(a), 0.05 * (k / 2));
    gt.push_back({0.1 * k, SE3(Quat::Identity(), p)});
    est.push_back({0.1 * k + 0.004, SE3(Quat::Identity(), p + Vec3(0, 0, k % 2 ? -d_m : d_m))});
  }
  io::writeTumTrajectory(tmp.file("gt.txt"), gt);
  io::writeTumTrajectory(tmp.file("est.txt"), est);
}

TEST(EvaluateCli, PrintsMetricsAndWritesTheSameKeysToJson) {
  TempDir tmp("eval_cli_ok");
  writeTrajectories(tmp, 0.03);
  fs::create_directories(tmp.file("gt_masks"));
  fs::create_directories(tmp.file("est_masks"));
  cv::Mat mask(4, 4, CV_8UC1, cv::Scalar(0));
  cv::imwrite(tmp.file("gt_masks/0.100000.png"), mask);
  mask(cv::Rect(0, 0, 2, 2)) = 255;
  cv::imwrite(tmp.file("est_masks/0.100000.png"), mask);  // static IoU 12/16
  const RunResult run =
      runEvaluate(tmp, "--gt " + tmp.file("gt.txt") + " --est " + tmp.file("est.txt") +
                           " --gt-masks " + tmp.file("gt_masks") + " --est-masks " +
                           tmp.file("est_masks") + " --json " + tmp.file("m.json"));
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const std::map<std::string, std::string> values = parseLines(run.out);
  for (const char* key : {"ate_rmse_m", "rpe_trans_rmse_m_s", "rpe_rot_rmse_deg_s", "static_iou",
                          "ate_mean_m", "ate_max_m", "rpe_trans_rmse_m_frame", "num_matched"}) {
    ASSERT_EQ(values.count(key), 1u) << key << " missing in:\n" << run.out;
  }
  EXPECT_NEAR(std::stod(values.at("ate_rmse_m")), 0.03, 1e-6);
  EXPECT_NEAR(std::stod(values.at("static_iou")), 0.75, 1e-9);
  EXPECT_EQ(values.at("num_matched"), "40");
  // The z offset flips every frame: each relative error is 2d = 0.06 m per 0.1 s frame.
  EXPECT_NEAR(std::stod(values.at("rpe_trans_rmse_m_frame")), 0.06, 1e-6);
  EXPECT_NEAR(std::stod(values.at("rpe_trans_rmse_m_s")), 0.6, 1e-5);
  EXPECT_NEAR(std::stod(values.at("rpe_rot_rmse_deg_s")), 0.0, 1e-6);
  const std::string json = readText(tmp.file("m.json"));
  for (const auto& [key, value] : values) {
    EXPECT_NE(json.find("\"" + key + "\": "), std::string::npos) << key;
  }
}

TEST(EvaluateCli, BadInputExitsTwoNamingFileLineAndValue) {
  TempDir tmp("eval_cli_bad");
  writeTrajectories(tmp, 0.0);
  io::test::replaceLine(tmp.file("est.txt"), 4, "0.204000 1 2 x 0 0 0 1");
  RunResult run = runEvaluate(tmp, "--gt " + tmp.file("gt.txt") + " --est " + tmp.file("est.txt"));
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find(tmp.file("est.txt") + ":4: value 4 is not a number: 'x'"),
            std::string::npos)
      << run.err;
  EXPECT_TRUE(run.out.empty());

  run = runEvaluate(tmp, "--gt " + tmp.file("missing.txt") + " --est " + tmp.file("gt.txt"));
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find(tmp.file("missing.txt") + ": cannot open"), std::string::npos) << run.err;

  run = runEvaluate(tmp,
                    "--gt " + tmp.file("gt.txt") + " --est " + tmp.file("gt.txt") + " --max-dt 0");
  EXPECT_EQ(run.exit_code, 2);  // a usage error is bad input too

  writeTrajectories(tmp, 0.0);
  run = runEvaluate(tmp, "--gt " + tmp.file("gt.txt") + " --est " + tmp.file("est.txt") +
                             " --max-dt 0.001");  // the estimate is 4 ms off: nothing matches
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("only 0 of 40 poses"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace ltlo
