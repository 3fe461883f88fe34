// ltlo::log line format, level filtering, thread names and the replaceable sink.
#include "ltlo/core/log.h"

#include <gtest/gtest.h>

#include <string>
#include <thread>
#include <vector>

#include "common/log_capture.h"

namespace ltlo {
namespace {

TEST(Log, LineCarriesThreadNameLevelAndMessage) {
  test::LogCapture capture(log::Level::kDebug);
  log::warn("imu.txt:812: gap of ", 0.12, " s");
  log::debug("n = ", 3);
  std::thread worker([] {
    log::setThreadName("tracking");
    log::error("lost");
  });
  worker.join();
  const std::vector<std::string> lines = capture.lines();
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0], "[main] warn imu.txt:812: gap of 0.12 s");
  EXPECT_EQ(lines[1], "[main] debug n = 3");
  EXPECT_EQ(lines[2], "[tracking] error lost");
}

TEST(Log, LevelFiltersLines) {
  test::LogCapture capture(log::Level::kInfo);
  const log::Level before = log::level();
  log::setLevel(log::Level::kWarn);
  log::info("dropped");
  log::warn("kept");
  log::setLevel(before);
  EXPECT_EQ(capture.lines(), std::vector<std::string>{"[main] warn kept"});
}

TEST(Log, ParsesLevelNames) {
  log::Level level = log::Level::kInfo;
  EXPECT_TRUE(log::parseLevel("trace", &level));
  EXPECT_EQ(level, log::Level::kTrace);
  EXPECT_TRUE(log::parseLevel("off", &level));
  EXPECT_EQ(level, log::Level::kOff);
  EXPECT_FALSE(log::parseLevel("verbose", &level));
  EXPECT_EQ(level, log::Level::kOff);  // unchanged on failure
}

TEST(Log, CaptureRestoresPreviousSink) {
  test::LogCapture outer;
  {
    test::LogCapture inner;
    log::info("inner");
    EXPECT_TRUE(inner.contains("inner"));
  }
  log::info("outer");
  EXPECT_EQ(outer.lines(), std::vector<std::string>{"[main] info outer"});
}

}  // namespace
}  // namespace ltlo
