#include "ltlo/io/imu_io.h"

#include <gtest/gtest.h>

#include "ltlo/io/associate.h"
#include "ltlo/io/metrics_json.h"

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
  const ImuSamples slice = imuBetween(imu, 0.105, 0.1325);
  ASSERT_EQ(slice.size(), 5u);  // 0.105, 0.11, 0.12, 0.13, 0.1325
  EXPECT_DOUBLE_EQ(slice.front().t_s, 0.105);
  EXPECT_DOUBLE_EQ(slice.back().t_s, 0.1325);
  EXPECT_NEAR(slice.front().gyro_rad_s.y(), 0.21, 1e-12);
  EXPECT_NEAR(slice.back().acc_m_s2.z(), 9.81 + 0.1325, 1e-12);
  EXPECT_DOUBLE_EQ(slice[1].t_s, imu[11].t_s);
}

TEST(ImuBetween, EndsOnSamplesAreNotDuplicatedAndIntervalsTile) {
  const ImuSamples imu = rampSamples(0.0, 0.01, 101);
  const ImuSamples a = imuBetween(imu, imu[10].t_s, imu[20].t_s);
  EXPECT_EQ(a.size(), 11u);
  const ImuSamples b = imuBetween(imu, imu[20].t_s, 0.255);
  EXPECT_EQ(a.back().t_s, b.front().t_s);  // shared boundary sample
  EXPECT_EQ(b.size(), 7u);                 // 0.20 .. 0.25 and 0.255
}

TEST(ImuBetween, ClipsToCoverageAndIsEmptyOutsideIt) {
  const ImuSamples imu = rampSamples(1.0, 0.01, 11);  // 1.0 .. 1.1 s
  EXPECT_TRUE(imuBetween(imu, 0.5, 0.9).empty());
  EXPECT_TRUE(imuBetween(imu, 1.2, 1.3).empty());
  EXPECT_TRUE(imuBetween({}, 0.0, 1.0).empty());
  const ImuSamples clipped = imuBetween(imu, 0.95, 1.025);
  ASSERT_EQ(clipped.size(), 4u);
  EXPECT_DOUBLE_EQ(clipped.front().t_s, 1.0);
  const ImuSamples single = imuBetween(imu, 1.055, 1.055);
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

}  // namespace
}  // namespace ltlo::io
