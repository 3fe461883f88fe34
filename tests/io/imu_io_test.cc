#include "ltlo/io/imu_io.h"

#include <gtest/gtest.h>

#include <sstream>

#include "common/log_capture.h"
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

// ---- rows as real drivers write them: repeated and reordered stamps, split sensor streams ----

using ltlo::test::inputErrorOf;
using ltlo::test::LogCapture;

// imu.txt text of full rows "t gx gy gz ax ay az" from (stamp, tag) pairs: gyro (tag, 0, 0),
// acc (0, 0, 9.81 + tag), so each row can be recognised after sorting.
std::string fullRows(const std::vector<std::pair<std::string, int>>& rows) {
  std::string text = "# timestamp gx gy gz ax ay az\n";
  for (const auto& [stamp, tag] : rows) {
    text += stamp + " " + std::to_string(tag) + " 0 0 0 0 " + std::to_string(9.81 + tag) + "\n";
  }
  return text;
}

std::vector<double> timesOf(const ImuSamples& imu) {
  std::vector<double> times_s;
  for (const ImuSample& s : imu) times_s.push_back(s.t_s);
  return times_s;
}

std::vector<int> tagsOf(const ImuSamples& imu) {
  std::vector<int> tags;
  for (const ImuSample& s : imu) tags.push_back(static_cast<int>(s.gyro_rad_s.x()));
  return tags;
}

int warningsIn(const LogCapture& capture) {
  int count = 0;
  for (const std::string& line : capture.lines()) count += line.find(" warn ") != std::string::npos;
  return count;
}

TEST(ImuStreams, DuplicatesDroppedFirstKeptAndLateRowsSorted) {
  test::TempDir tmp("imu_reorder");
  const std::string path = tmp.file("imu.txt");
  // Lines 2..12. 1.010 repeats exactly (line 4) and with other values (line 9); 1.005 and 1.025
  // arrive late (lines 6 and 10, 5 ms and 15 ms behind); 1.020 repeats the late-sorted region.
  test::writeText(path, fullRows({{"1.000", 1}, {"1.010", 2}, {"1.010", 2}, {"1.020", 3},
                                  {"1.005", 4}, {"1.030", 5}, {"1.040", 6}, {"1.010", 7},
                                  {"1.025", 8}, {"1.050", 9}, {"1.020", 10}}));
  LogCapture capture(log::Level::kInfo);
  const ImuSamples imu = readImuText(path, SequenceOptions{});
  EXPECT_EQ(timesOf(imu), (std::vector<double>{1.000, 1.005, 1.010, 1.020, 1.025, 1.030, 1.040, 1.050}));
  EXPECT_EQ(tagsOf(imu), (std::vector<int>{1, 4, 2, 3, 8, 5, 6, 9}));
  EXPECT_EQ(imu[2].acc_m_s2, Vec3(0, 0, 9.81 + 2));  // the first row of 1.010 (line 3), all values
  // Lines 4 (exact), 9 and 12 (other values) dropped; lines 6 and 10 sorted.
  EXPECT_TRUE(capture.contains(path + ": 3 duplicated stamps dropped (2 with values other than the "
                                      "first's; first at line 4), 2 samples out of order sorted "
                                      "(first at line 6)"));
  EXPECT_EQ(warningsIn(capture), 1);
  EXPECT_EQ(capture.lines().size(), 1u);  // and nothing else
}

TEST(ImuStreams, CleanFileIsReadAsWrittenWithoutAWord) {
  test::TempDir tmp("imu_clean");
  const std::string path = tmp.file("imu.txt");
  // Uneven spacing and jitter are not an error, nor worth a line.
  test::writeText(path, fullRows({{"1.0000", 1}, {"1.0049", 2}, {"1.0101", 3}, {"1.0300", 4}}));
  LogCapture capture(log::Level::kInfo);
  const ImuSamples imu = readImuText(path, SequenceOptions{});
  EXPECT_EQ(timesOf(imu), (std::vector<double>{1.0, 1.0049, 1.0101, 1.03}));
  EXPECT_EQ(tagsOf(imu), (std::vector<int>{1, 2, 3, 4}));
  EXPECT_TRUE(capture.lines().empty());
}

TEST(ImuStreams, ReorderLimitIsInclusiveAndZeroAllowsNoStepBack) {
  test::TempDir tmp("imu_reorder_limit");
  const std::string path = tmp.file("imu.txt");
  // 1.25 is exactly 0.25 s behind 1.5 (both exact binary fractions).
  test::writeText(path, fullRows({{"1.0", 1}, {"1.5", 2}, {"1.25", 3}, {"1.75", 4}}));
  SequenceOptions options;
  options.max_imu_gap_s = 1.0;
  options.max_imu_reorder_s = 0.25;
  EXPECT_EQ(tagsOf(readImuText(path, options)), (std::vector<int>{1, 3, 2, 4}));
  options.max_imu_reorder_s = 0.0;
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readImuText(path, options); }),
                       path + ":4: timestamp 1.250000 goes back by 0.250000 s behind 1.500000 "
                              "(line 3), more than Sequence.MaxImuReorder = 0 s");
  // A repeated stamp is no step back: dropped even with a zero limit.
  test::writeText(path, fullRows({{"1.0", 1}, {"1.5", 2}, {"1.5", 3}, {"1.75", 4}}));
  EXPECT_EQ(tagsOf(readImuText(path, options)), (std::vector<int>{1, 2, 4}));
}

TEST(ImuStreams, JumpBackBeyondTheLimitIsAnError) {
  test::TempDir tmp("imu_jump_back");
  const std::string path = tmp.file("imu.txt");
  // Two recordings joined: the second starts again at 1.000 after 1.500 (line 7).
  test::writeText(path, fullRows({{"1.000", 1}, {"1.125", 2}, {"1.250", 3}, {"1.375", 4},
                                  {"1.500", 5}, {"1.000", 6}, {"1.125", 7}}));
  SequenceOptions options;
  options.max_imu_gap_s = 1.0;
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readImuText(path, options); }),
                       path + ":7: timestamp 1.000000 goes back by 0.500000 s behind 1.500000 "
                              "(line 6), more than Sequence.MaxImuReorder = 0.1 s (a clock reset, "
                              "or two files joined?)");
  // The same in EuRoC nanoseconds, and in one OpenLORIS file (the accelerometer's clock reset).
  const std::string csv = tmp.file("data.csv");
  test::writeText(csv, "1000000000,0,0,0,0,0,9.8\n1200000000,0,0,0,0,0,9.8\n1050000000,0,0,0,0,0,9.8\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readEurocImuCsv(csv, options); }),
                       csv + ":3: timestamp 1.050000 goes back by 0.150000 s behind 1.200000 (line 2)");
  test::writeText(tmp.file("accel.txt"), "1.00 0 0 9.8\n1.01 0 0 9.8\n0.50 0 0 9.8\n");
  test::writeText(tmp.file("gyro.txt"), "1.00 0 0 0\n1.01 0 0 0\n");
  LTLO_EXPECT_CONTAINS(
      inputErrorOf([&] { readOpenLorisImu(tmp.file("accel.txt"), tmp.file("gyro.txt"), options); }),
      tmp.file("accel.txt") + ":3: timestamp 0.500000 goes back by 0.510000 s behind 1.010000 (line 2)");
}

TEST(ImuStreams, EurocAndOpenLorisDropDuplicatesAndSortWithOneWarningPerFile) {
  test::TempDir tmp("imu_reorder_other");
  const std::string csv = tmp.file("data.csv");
  test::writeText(csv,
                  "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n"
                  "1000000000,1,0,0,0,0,9.8\n"
                  "1010000000,3,0,0,0,0,9.8\n"
                  "1005000000,2,0,0,0,0,9.8\n"
                  "1010000000,3,0,0,0,0,9.8\n");
  {
    LogCapture capture(log::Level::kWarn);
    const ImuSamples imu = readEurocImuCsv(csv, SequenceOptions{});
    EXPECT_EQ(tagsOf(imu), (std::vector<int>{1, 2, 3}));
    EXPECT_TRUE(capture.contains(csv + ": 1 duplicated stamps dropped (first at line 5), 1 samples "
                                       "out of order sorted (first at line 4)"));
    EXPECT_EQ(warningsIn(capture), 1);
  }
  // OpenLORIS: gyro.txt repeats and reorders, accel.txt is clean; the union merge is unchanged.
  test::writeText(tmp.file("accel.txt"), "1.000 0 0 9.8\n1.004 0 0 9.8\n1.008 0 0 9.8\n1.012 0 0 9.8\n");
  test::writeText(tmp.file("gyro.txt"), "1.000 1 0 0\n1.010 3 0 0\n1.005 2 0 0\n1.005 9 0 0\n");
  LogCapture capture(log::Level::kInfo);
  const ImuSamples imu = readOpenLorisImu(tmp.file("accel.txt"), tmp.file("gyro.txt"), SequenceOptions{});
  EXPECT_EQ(timesOf(imu), (std::vector<double>{1.000, 1.004, 1.005, 1.008, 1.010}));
  EXPECT_NEAR(imu[1].gyro_rad_s.x(), 1.8, 1e-12);  // 1 -> 2 over 1.000 .. 1.005
  EXPECT_NEAR(imu[3].gyro_rad_s.x(), 2.6, 1e-12);  // 2 -> 3 over 1.005 .. 1.010
  EXPECT_TRUE(capture.contains(tmp.file("gyro.txt") + ": 1 duplicated stamps dropped (1 with values "
                                                      "other than the first's; first at line 4), 1 "
                                                      "samples out of order sorted (first at line 3)"));
  EXPECT_EQ(warningsIn(capture), 1);
  EXPECT_TRUE(capture.contains(": merged at the union of their stamps inside [1.000000, 1.010000] s, "
                               "5 samples (1 stamps outside it dropped)"));
}

// A split stream: gyro-only rows, accel-only rows and full rows (both) merged at the gyro stamps.
TEST(ImuStreams, SplitStreamMergesOntoGyroStamps) {
  test::TempDir tmp("imu_split");
  const std::string path = tmp.file("imu.txt");
  // Accelerometer az = 10 + 100 t at 1.000, 1.008 (full row), 1.016, 1.024; the gyroscope at
  // 0.996 (before the accelerometer: dropped), 1.002, 1.008 (full), 1.012, 1.018, 1.030 (after:
  // dropped). Rows come as a driver interleaves them, per sensor in order; NaN in any case.
  test::writeText(path,
                  "# timestamp gx gy gz ax ay az\n"
                  "0.996 0.1 0 0 nan nan nan\n"
                  "1.000 NaN NaN NaN 0 0 110\n"
                  "1.002 0.2 0 0 nan nan nan\n"
                  "1.008 0.3 0 0 0 0 110.8\n"
                  "1.012 0.4 0 0 NAN nan Nan\n"
                  "1.016 nan nan nan 0 0 111.6\n"
                  "1.018 0.5 0 0 nan nan nan\n"
                  "1.024 -nan -nan -nan 0 0 112.4\n"
                  "1.030 0.6 0 0 nan nan nan\n");
  LogCapture capture(log::Level::kInfo);
  const ImuSamples imu = readImuText(path, SequenceOptions{});
  EXPECT_EQ(timesOf(imu), (std::vector<double>{1.002, 1.008, 1.012, 1.018}));
  const std::vector<double> gx = {0.2, 0.3, 0.4, 0.5};
  for (size_t i = 0; i < imu.size(); ++i) {
    EXPECT_EQ(imu[i].gyro_rad_s, Vec3(gx[i], 0, 0)) << i;  // as read, not interpolated
    EXPECT_NEAR(imu[i].acc_m_s2.z(), 10.0 + 100.0 * imu[i].t_s, 1e-9) << i;
    EXPECT_EQ(imu[i].acc_m_s2.x(), 0.0);
  }
  EXPECT_EQ(imu[1].acc_m_s2.z(), 110.8);  // the full row's own accelerometer reading
  EXPECT_TRUE(capture.contains(path + ": split stream: accelerometer (4 samples) interpolated at the "
                                      "gyroscope's 6 stamps; 2 gyroscope samples outside the "
                                      "accelerometer's span [1.000000, 1.024000] s dropped"));
  EXPECT_EQ(capture.lines().size(), 1u);  // per sensor in order: no reorder warning
}

TEST(ImuStreams, SplitStreamOrdersEachSensorOnItsOwn) {
  test::TempDir tmp("imu_split_order");
  const std::string path = tmp.file("imu.txt");
  // A gyro-only and an accel-only row at 1.010 are two sensors, not a duplicate. The gyroscope
  // repeats 1.010 (line 6: dropped) and sends 1.005 late (line 7); the accelerometer repeats
  // 1.020 exactly (line 9: dropped).
  test::writeText(path,
                  "1.000 1 0 0 0 0 10\n"
                  "1.010 3 0 0 nan nan nan\n"
                  "1.010 nan nan nan 0 0 11\n"
                  "1.020 nan nan nan 0 0 12\n"
                  "1.010 4 0 0 nan nan nan\n"
                  "1.005 2 0 0 nan nan nan\n"
                  "1.015 5 0 0 nan nan nan\n"
                  "1.020 nan nan nan 0 0 12\n");
  LogCapture capture(log::Level::kWarn);
  const ImuSamples imu = readImuText(path, SequenceOptions{});
  EXPECT_EQ(timesOf(imu), (std::vector<double>{1.000, 1.005, 1.010, 1.015}));
  EXPECT_EQ(tagsOf(imu), (std::vector<int>{1, 2, 3, 5}));
  EXPECT_NEAR(imu[1].acc_m_s2.z(), 10.5, 1e-12);
  EXPECT_EQ(imu[2].acc_m_s2.z(), 11.0);
  EXPECT_TRUE(capture.contains(path + ": 2 duplicated stamps dropped (1 with values other than the "
                                      "first's; first at line 5), 1 samples out of order sorted "
                                      "(first at line 6) [gyroscope 1 dropped, 1 sorted; "
                                      "accelerometer 1 dropped, 0 sorted]"));
  EXPECT_EQ(warningsIn(capture), 1);
}

TEST(ImuStreams, MalformedHalfRowsNameFileLineAndValue) {
  test::TempDir tmp("imu_half_rows");
  const std::string path = tmp.file("imu.txt");
  const std::string good = "1.000 0.1 0.2 0.3 nan nan nan\n1.001 nan nan nan 1 2 9.8\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"1.002 0.1 nan 0.3 1 2 9.8",
       ":3: value 3 is not finite: 'nan' (the gyroscope triple '0.1 nan 0.3' is partly nan; a "
       "sensor missing from a row is written 'nan nan nan')"},
      {"1.002 NaN nan 0.3 1 2 9.8",
       ":3: value 2 is not finite: 'NaN' (the gyroscope triple 'NaN nan 0.3'"},
      {"1.002 0.1 0.2 0.3 1 2 nan",
       ":3: value 7 is not finite: 'nan' (the accelerometer triple '1 2 nan'"},
      {"1.002 nan nan nan nan 2 NAN",
       ":3: value 5 is not finite: 'nan' (the accelerometer triple 'nan 2 NAN'"},
      {"1.002 nan nan nan nan nan nan",
       ":3: both sensors missing (gyroscope and accelerometer 'nan nan nan') in "
       "'1.002 nan nan nan nan nan nan'"},
      {"1.002 nan nan nan 1 2", ":3: expected 7 values, found 6 in '1.002 nan nan nan 1 2'"},
      {"1.002 nan nan nan 1 inf 9.8", ":3: value 6 is not finite: 'inf'"},
      {"1.002 nan nan nan 1 nanx 9.8", ":3: value 6 is not a number: 'nanx'"},
      {"nan 0.1 0.2 0.3 nan nan nan", ":3: timestamp is not finite: 'nan'"},
  };
  for (const auto& [line, message] : cases) {
    SCOPED_TRACE(line);
    test::writeText(path, good + line + "\n");
    LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readImuText(path, SequenceOptions{}); }), path + message);
  }
  // EuRoC has no half rows: nan is a non-finite value there.
  const std::string csv = tmp.file("data.csv");
  test::writeText(csv, "1000000000,nan,nan,nan,1,2,9.8\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readEurocImuCsv(csv, SequenceOptions{}); }),
                       csv + ":1: value 2 is not finite: 'nan'");
}

TEST(ImuStreams, SplitStreamWithoutOneSensorOrOverlapIsAnError) {
  test::TempDir tmp("imu_split_errors");
  const std::string path = tmp.file("imu.txt");
  test::writeText(path, "1.000 0.1 0 0 nan nan nan\n1.005 0.1 0 0 nan nan nan\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readImuText(path, SequenceOptions{}); }),
                       path + ": no accelerometer samples");
  test::writeText(path, "1.000 nan nan nan 0 0 9.8\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readImuText(path, SequenceOptions{}); }),
                       path + ": no gyroscope samples");
  test::writeText(path, "1.000 0.1 0 0 nan nan nan\n1.010 nan nan nan 0 0 9.8\n1.020 nan nan nan 0 0 9.8\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readImuText(path, SequenceOptions{}); }),
                       path + ": gyroscope times [1.000000, 1.000000] do not overlap the "
                              "accelerometer's [1.010000, 1.020000]");
  test::writeText(path, "1.000 0.1 0 0 nan nan nan\n1.010 nan nan nan 0 0 9.8\n"
                        "1.020 nan nan nan 0 0 9.8\n1.030 0.1 0 0 nan nan nan\n");
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readImuText(path, SequenceOptions{}); }),
                       path + ": none of the 2 gyroscope stamps lies inside the accelerometer's span "
                              "[1.010000, 1.020000]");
}

TEST(ImuStreams, SplitStreamGapsAreCheckedPerSensor) {
  test::TempDir tmp("imu_split_gaps");
  const std::string path = tmp.file("imu.txt");
  // The gyroscope is dense, the accelerometer skips 1.01 .. 1.09 (0.1 s; line 12 after it).
  std::ostringstream text;
  for (int k = 0; k <= 10; ++k) {
    const double t_s = 1.0 + 0.01 * k;
    text << t_s << " 0.1 0 0 " << (k == 0 || k == 10 ? "0 0 9.8" : "nan nan nan") << "\n";
  }
  text << "1.101 0.1 0 0 nan nan nan\n";
  test::writeText(path, text.str());
  SequenceOptions options;
  options.imu_gap_policy = ImuGapPolicy::kFail;
  LTLO_EXPECT_CONTAINS(inputErrorOf([&] { readImuText(path, options); }),
                       path + ":11: accelerometer gap of 0.100 s before t = 1.100000 s (limit 0.050 s)");
  options.max_imu_gap_s = 0.2;
  EXPECT_EQ(readImuText(path, options).size(), 11u);  // 1.101 is past the accelerometer
}

}  // namespace
}  // namespace ltlo::io
