// ltlo::log line format, level filtering, thread names and the replaceable sink.
#include "ltlo/core/log.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/log_capture.h"
#include "ltlo/core/thread_names.h"

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

// A named thread is listed while it runs and never after its join() returned, for many threads in
// a row (the kernel's task list may still show a joined thread for a moment: the list must not).
TEST(ThreadNames, NamedThreadsAreListedUntilJoined) {
  const auto listed = [](const std::string& os_name) {
    const std::vector<std::string> names = runningNamedThreads();
    return std::count(names.begin(), names.end(), os_name);
  };
  for (int i = 0; i < 200; ++i) {
    std::mutex mutex;
    std::condition_variable cv;
    bool named = false, release = false;
    std::thread worker([&] {
      log::setThreadName("segmentation");
      log::setThreadName("worker");  // renamed: listed once, under the new name
      std::unique_lock<std::mutex> lock(mutex);
      named = true;
      cv.notify_all();
      cv.wait(lock, [&] { return release; });
    });
    long while_running = 0, old_name = 0;
    {
      std::unique_lock<std::mutex> lock(mutex);
      cv.wait(lock, [&] { return named; });
      while_running = listed("ltlo.worker");
      old_name = listed("ltlo.segmentati");
      release = true;
    }
    cv.notify_all();
    worker.join();
    ASSERT_EQ(while_running, 1) << "run " << i;
    ASSERT_EQ(old_name, 0) << "run " << i;
    ASSERT_EQ(listed("ltlo.worker"), 0) << "run " << i;
  }
}

}  // namespace
}  // namespace ltlo
