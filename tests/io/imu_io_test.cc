#include "ltlo/io/imu_io.h"

#include <gtest/gtest.h>

#include "expect_input_error.h"
#include "ltlo/io/associate.h"
#include "ltlo/io/metrics_json.h"
#include "test_sequence_writer.h"

namespace ltlo::io {
namespace {

ImuSamples rampSamples(double t0_s, double dt_s, int count) {
  ImuSamples samples;
  for (int k = 0; k < count; ++k) {
    const double t_s = t0_s + k * dt_s;
    samples.push_back({t_s, Vec3(t_s, 2 * t_s, -t_s), Vec3(1, 0, 9.81 + t_s)});
  }
  return samples;
}

TEST(ImuBetween, InterpolatesBothEndsAndKeepsInteriorSamples) {
  const ImuSamples imu = rampSamples(0.0, 0.01, 101);  // 0 .. 1 s
  const ImuSamples slice = imuSamplesBetween(imu, 0.105, 0.1325);
  ASSERT_EQ(slice.size(), 5u);  // 0.105, 0.11, 0.12, 0.13, 0.1325
  EXPECT_DOUBLE_EQ(slice.front().t_s, 0.105);
  EXPECT_DOUBLE_EQ(slice.back().t_s, 0.1325);
  EXPECT_NEAR(slice.front().gyro_rad_s.y(), 0.21, 1e-12);
  EXPECT_NEAR(slice.back().acc_m_s2.z(), 9.81 + 0.1325, 1e-12);
  EXPECT_DOUBLE_EQ(slice[1].t_s, imu[11].t_s);
}

TEST(ImuBetween, EndsOnSamplesAreNotDuplicatedAndIntervalsTile) {
  const ImuSamples imu = rampSamples(0.0, 0.01, 101);
  const ImuSamples a = imuSamplesBetween(imu, imu[10].t_s, imu[20].t_s);
  EXPECT_EQ(a.size(), 11u);
  const ImuSamples b = imuSamplesBetween(imu, imu[20].t_s, 0.255);
  EXPECT_EQ(a.back().t_s, b.front().t_s);  // shared boundary sample
  EXPECT_EQ(b.size(), 7u);                 // 0.20 .. 0.25 and 0.255
}

TEST(ImuBetween, ClipsToCoverageAndIsEmptyOutsideIt) {
  const ImuSamples imu = rampSamples(1.0, 0.01, 11);  // 1.0 .. 1.1 s
  EXPECT_TRUE(imuSamplesBetween(imu, 0.5, 0.9).empty());
  EXPECT_TRUE(imuSamplesBetween(imu, 1.2, 1.3).empty());
  EXPECT_TRUE(imuSamplesBetween({}, 0.0, 1.0).empty());
  const ImuSamples clipped = imuSamplesBetween(imu, 0.95, 1.025);
  ASSERT_EQ(clipped.size(), 4u);
  EXPECT_DOUBLE_EQ(clipped.front().t_s, 1.0);
  const ImuSamples single = imuSamplesBetween(imu, 1.055, 1.055);
  ASSERT_EQ(single.size(), 1u);
  EXPECT_NEAR(single[0].gyro_rad_s.x(), 1.055, 1e-12);
}

TEST(AssociateTimestamps, NearestFirstAndOneToOne) {
  // 1.0 could take 0.99 or 1.005: the nearer wins. 1.01 and 1.0 both want 1.006: 1.01 is nearer,
  // so 1.0 falls back to 0.99 (within tolerance), as in the TUM associate tool.
  const std::vector<std::pair<int, int>> pairs =
      associateTimestamps({1.0, 1.01}, {0.99, 1.006}, 0.02);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0], std::make_pair(0, 0));
  EXPECT_EQ(pairs[1], std::make_pair(1, 1));
  const std::vector<std::pair<int, int>> tight = associateTimestamps({1.0, 1.01}, {1.006}, 0.02);
  ASSERT_EQ(tight.size(), 1u);
  EXPECT_EQ(tight[0], std::make_pair(1, 0));
  EXPECT_TRUE(associateTimestamps({1.0}, {1.03}, 0.02).empty());
  EXPECT_TRUE(associateTimestamps({}, {1.0}, 0.02).empty());
}

TEST(Metrics, TextAndJsonHaveTheSameKeysInOrder) {
  Metrics metrics;
  metrics.set("ate_rmse_m", 0.0123456789012);
  metrics.set("num_matched", 42);
  metrics.set("alignment", "se3");
  metrics.set("bad", std::nan(""));
  metrics.set("ate_rmse_m", 0.5);  // replaces, keeps the position
  EXPECT_EQ(metrics.toText(), "ate_rmse_m 0.5\nnum_matched 42\nalignment se3\nbad nan\n");
  EXPECT_EQ(metrics.toJson(),
            "{\n  \"ate_rmse_m\": 0.5,\n  \"num_matched\": 42,\n  \"alignment\": \"se3\",\n"
            "  \"bad\": null\n}\n");
  EXPECT_DOUBLE_EQ(metrics.number("num_matched"), 42.0);
  EXPECT_THROW(metrics.number("alignment"), std::out_of_range);
  Metrics quoted;
  quoted.set("path", "a\"b\\c");
  EXPECT_EQ(quoted.toJson(), "{\n  \"path\": \"a\\\"b\\\\c\"\n}\n");
}

TEST(ImuFiles, EurocCsvReadsNanosecondsAndRejectsOtherTimestamps) {
  test::TempDir tmp("imu_euroc_csv");
  const std::string path = tmp.file("data.csv");
  test::writeText(path,
                  "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n"
                  "1403636579758555392,0.1,0.2,0.3,1,2,9.8\n"
                  "1403636579763555584,0.1,0.2,0.3,1,2,9.8\n");
  const ImuSamples imu = readEurocImuCsv(path, SequenceOptions{});
  ASSERT_EQ(imu.size(), 2u);
  // Seconds as doubles near 1.4e9 are spaced 2.4e-7 s apart: that is the resolution left.
  EXPECT_NEAR(imu[0].t_s, 1403636579.758555392, 2.4e-7);
  EXPECT_NEAR(imu[1].t_s - imu[0].t_s, 0.005000192, 2.4e-7);
  EXPECT_EQ(imu[0].acc_m_s2, Vec3(1, 2, 9.8));
  test::writeText(path, "1403636579.758,0.1,0.2,0.3,1,2,9.8\n");
  LTLO_EXPECT_CONTAINS(
      ltlo::test::inputErrorOf([&] { readEurocImuCsv(path, SequenceOptions{}); }),
      path + ":1: timestamp is not a non-negative integer of nanoseconds: '1403636579.758'");
}

TEST(ImuFiles, OpenLorisStreamsMustOverlap) {
  test::TempDir tmp("imu_openloris_overlap");
  test::writeText(tmp.file("accel.txt"), "1.00 0 0 9.8\n1.01 0 0 9.8\n");
  test::writeText(tmp.file("gyro.txt"), "2.00 0 0 0\n2.01 0 0 0\n");
  SequenceOptions options;
  options.max_imu_gap_s = 1.0;
  LTLO_EXPECT_CONTAINS(
      ltlo::test::inputErrorOf(
          [&] { readOpenLorisImu(tmp.file("accel.txt"), tmp.file("gyro.txt"), options); }),
      tmp.file("gyro.txt") + ": gyroscope times [2.000000, 2.010000] do not overlap");
}

}  // namespace
}  // namespace ltlo::io
