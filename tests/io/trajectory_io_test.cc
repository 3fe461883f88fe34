#include "ltlo/io/trajectory_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "common/log_capture.h"
#include "expect_input_error.h"
#include "ltlo/core/errors.h"
#include "test_sequence_writer.h"

namespace ltlo::io {
namespace {

using ltlo::test::inputErrorOf;
using test::TempDir;

Trajectory randomTrajectory(double t0_s, double dt_s, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(-3.0, 3.0);
  Trajectory trajectory;
  for (int k = 0; k < count; ++k) {
    const Vec3 phi(uniform(rng), uniform(rng), uniform(rng));
    trajectory.push_back({t0_s + k * dt_s, SE3(so3ExpQuat(0.5 * phi),
                                               Vec3(uniform(rng), uniform(rng), uniform(rng)))});
  }
  return trajectory;
}

void expectSameTrajectory(const Trajectory& a, const Trajectory& b, double tolerance) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_NEAR(a[k].t_s, b[k].t_s, tolerance) << "pose " << k;
    EXPECT_LT((a[k].T_w_x.translation() - b[k].T_w_x.translation()).norm(), tolerance);
    EXPECT_LT(a[k].T_w_x.quaternion().angularDistance(b[k].T_w_x.quaternion()), tolerance);
  }
}

TEST(TrajectoryIo, TumRoundTripKeepsNanosecondsAndFullPosePrecision) {
  TempDir tmp("traj_tum");
  for (const double t0_s : {0.0, 12.345678901, 1305031102.175304}) {
    const Trajectory original = randomTrajectory(t0_s, 0.0333, 50, 3);
    writeTumTrajectory(tmp.file("t.txt"), original);
    const Trajectory read = readTumTrajectory(tmp.file("t.txt"));
    expectSameTrajectory(original, read, 1e-9);
    // Epoch times (spacing of doubles ~2e-7 s): 9 decimals give back the very same double.
    if (t0_s > 1e9) {
      EXPECT_EQ(read.back().t_s, original.back().t_s);
    }
  }
}

TEST(TrajectoryIo, EurocRoundTripKeepsNanosecondsAndFullPosePrecision) {
  TempDir tmp("traj_euroc");
  for (const double t0_s : {0.0, 12.345678901, 1403636579.758555}) {
    const Trajectory original = randomTrajectory(t0_s, 0.005, 50, 4);
    writeEurocTrajectory(tmp.file("t.csv"), original);
    const Trajectory read = readEurocTrajectory(tmp.file("t.csv"));
    expectSameTrajectory(original, read, 1e-9);
  }
}

TEST(TrajectoryIo, EurocWritesTheNanosecondNearestToEpochTimes) {
  // llround(t_s * 1e9) rounds the product to a multiple of 256 ns near 1.4e18; the writer must
  // give the nanosecond nearest to the double instead.
  TempDir tmp("traj_euroc_ns");
  writeEurocTrajectory(tmp.file("t.csv"), {{1403636579.758555, SE3()}});
  const std::string text = test::readText(tmp.file("t.csv"));
  const std::string first_field = text.substr(text.find('\n') + 1, 19);
  // 1403636579.758555 is stored as 1403636579.7585549354553222656...
  EXPECT_EQ(first_field, "1403636579758554935");
}

TEST(TrajectoryIo, EurocIgnoresExtraColumnsAndReadsSeconds) {
  TempDir tmp("traj_euroc_extra");
  test::writeText(tmp.file("gt.csv"),
                  "#timestamp,p_x,p_y,p_z,q_w,q_x,q_y,q_z,v_x\n"
                  "1000000001,1,2,3,1,0,0,0,9\n"
                  "2500000000,4,5,6,0,1,0,0,9\n");
  const Trajectory read = readEurocTrajectory(tmp.file("gt.csv"));
  ASSERT_EQ(read.size(), 2u);
  EXPECT_DOUBLE_EQ(read[0].t_s, 1.000000001);
  EXPECT_DOUBLE_EQ(read[1].t_s, 2.5);
  EXPECT_EQ(read[1].T_w_x.translation(), Vec3(4, 5, 6));
  EXPECT_NEAR(read[1].T_w_x.quaternion().x(), 1.0, 1e-15);
}

TEST(TrajectoryIoErrors, TumMessagesNameFileLineAndValue) {
  TempDir tmp("traj_tum_err");
  const std::string path = tmp.file("t.txt");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readTumTrajectory(tmp.file("missing.txt")); }),
                       tmp.file("missing.txt") + ": cannot open trajectory file");
  const std::string good = "# header\n1.0 0 0 0 0 0 0 1\n";
  test::writeText(path, good + "2.0 0 0 0 0 0 1\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readTumTrajectory(path); }),
                       path + ":3: expected 8 values, found 7");
  test::writeText(path, good + "2.0 0 0 0 0 0 0 1 5\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readTumTrajectory(path); }),
                       path + ":3: expected 8 values, found 9");
  test::writeText(path, good + "2.0 0 zero 0 0 0 0 1\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readTumTrajectory(path); }),
                       path + ":3: value 3 is not a number: 'zero'");
  test::writeText(path, good + "2.0 0 0 nan 0 0 0 1\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readTumTrajectory(path); }),
                       path + ":3: value 4 is not finite: 'nan'");
  test::writeText(path, good + "1.0 0 0 0 0 0 0 1\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readTumTrajectory(path); }),
                       path + ":3: timestamp 1 does not increase (previous 1)");
  test::writeText(path, good + "2.0 0 0 0 0 0 0 0\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readTumTrajectory(path); }),
                       path + ":3: quaternion (qx qy qz qw) = (0 0 0 0) has norm 0, cannot be normalised");
}

TEST(TrajectoryIo, NonUnitQuaternionsAreNormalisedWithOneWarningPerFile) {
  TempDir tmp("traj_non_unit");
  const std::string path = tmp.file("t.txt");
  // Line 2 is unit to 4 decimals (TUM ground truth style: no warning), lines 3 and 4 are not.
  test::writeText(path,
                  "# t tx ty tz qx qy qz qw\n"
                  "1.0 0 0 0 0.7071 0 0 0.7071\n"
                  "2.0 1 2 3 0 0 0 2\n"
                  "3.0 1 2 3 0 0.6 0 0.78\n");
  ltlo::test::LogCapture capture(log::Level::kWarn);
  const Trajectory read = readTumTrajectory(path);
  ASSERT_EQ(read.size(), 3u);
  for (const StampedPose& pose : read) EXPECT_NEAR(pose.T_w_x.quaternion().norm(), 1.0, 1e-15);
  EXPECT_NEAR(read[1].T_w_x.quaternion().w(), 1.0, 1e-15);
  EXPECT_NEAR(read[2].T_w_x.quaternion().y(), 0.6 / std::hypot(0.6, 0.78), 1e-15);
  EXPECT_EQ(read[1].T_w_x.translation(), Vec3(1, 2, 3));
  ASSERT_EQ(capture.lines().size(), 1u);
  LTLO_EXPECT_CONTAINS(capture.lines()[0], path + ":3: 2 of 3 quaternions are not unit (norms 0.984");
  LTLO_EXPECT_CONTAINS(capture.lines()[0], "far from 1");

  const std::string csv = tmp.file("t.csv");
  test::writeText(csv, "#t,px,py,pz,qw,qx,qy,qz\n1000,0,0,0,0.99,0,0,0\n");
  ltlo::test::LogCapture csv_capture(log::Level::kWarn);
  EXPECT_NEAR(readEurocTrajectory(csv)[0].T_w_x.quaternion().w(), 1.0, 1e-15);
  EXPECT_TRUE(csv_capture.contains(csv + ":2: 1 of 1 quaternions are not unit"));
}

TEST(TrajectoryIo, WritersReplaceTheFileOnlyWhenComplete) {
  TempDir tmp("traj_atomic");
  const std::string path = tmp.file("t.txt");
  test::writeText(path, "previous content\n");
  writeTumTrajectory(path, randomTrajectory(0.0, 0.1, 3, 5));
  EXPECT_EQ(readTumTrajectory(path).size(), 3u);
  EXPECT_FALSE(std::filesystem::exists(path + ".part"));
  writeEurocTrajectory(tmp.file("t.csv"), randomTrajectory(0.0, 0.1, 2, 5));
  EXPECT_EQ(readEurocTrajectory(tmp.file("t.csv")).size(), 2u);
  EXPECT_FALSE(std::filesystem::exists(tmp.file("t.csv.part")));
}

TEST(TrajectoryIoErrors, EurocMessagesNameFileLineAndValue) {
  TempDir tmp("traj_euroc_err");
  const std::string path = tmp.file("t.csv");
  const std::string good = "#timestamp\n1000,0,0,0,1,0,0,0\n";
  test::writeText(path, good + "1.5e9,0,0,0,1,0,0,0\n");
  LTLO_EXPECT_CONTAINS(
      inputErrorOf([&] { readEurocTrajectory(path); }),
      path + ":3: timestamp is not a non-negative integer of nanoseconds: '1.5e9'");
  test::writeText(path, good + "2000,0,0,0,1,0,0\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readEurocTrajectory(path); }),
                       path + ":3: expected 8 values, found 7");
  test::writeText(path, good + "500,0,0,0,1,0,0,0\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readEurocTrajectory(path); }), path + ":3: timestamp");
  test::writeText(path, good + "2000,0,0,0,1,inf,0,0\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readEurocTrajectory(path); }),
                       path + ":3: value 6 is not finite: 'inf'");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { writeEurocTrajectory(tmp.file("no/such/dir.csv"), {}); }),
                       tmp.file("no/such/dir.csv") + ": cannot open for writing");
}

}  // namespace
}  // namespace ltlo::io
