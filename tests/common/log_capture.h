#pragma once
/// Captures ltlo::log lines for the lifetime of the object, so tests can assert on warnings
/// (STYLE.md section 9: error paths with their message text). Restores the previous sink on
/// destruction. Captures lines from every thread; not for nesting across threads.
///
///   test::LogCapture capture;
///   Settings::load(path_with_typo);
///   EXPECT_TRUE(capture.contains("unknown key Seg.Clustres"));
#include <algorithm>
#include <mutex>
#include <string>
#include <vector>

#include "ltlo/core/log.h"

namespace ltlo::test {

class LogCapture {
 public:
  /// Captures lines at `level` and above (the global level is lowered for the capture if needed).
  explicit LogCapture(log::Level level = log::Level::kInfo) : previous_level_(log::level()) {
    if (level < previous_level_) log::setLevel(level);
    previous_sink_ = log::setSink([this, level](log::Level line_level, const std::string& line) {
      if (line_level < level) return;
      std::lock_guard<std::mutex> lock(mutex_);
      lines_.push_back(line);
    });
  }
  LogCapture(const LogCapture&) = delete;
  LogCapture& operator=(const LogCapture&) = delete;
  ~LogCapture() {
    log::setSink(previous_sink_);
    log::setLevel(previous_level_);
  }

  /// Every captured line, "[thread] level message".
  std::vector<std::string> lines() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return lines_;
  }
  /// True when some captured line contains `text`.
  bool contains(const std::string& text) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::any_of(lines_.begin(), lines_.end(), [&](const std::string& line) {
      return line.find(text) != std::string::npos;
    });
  }

 private:
  mutable std::mutex mutex_;  // guards lines_ (the sink may be called from any thread)
  std::vector<std::string> lines_;
  log::Sink previous_sink_;
  log::Level previous_level_;
};

}  // namespace ltlo::test
