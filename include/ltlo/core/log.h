#pragma once
/// Levelled logger (STYLE.md section 8): one line per event, thread name first, e.g.
///   [tracking] warn imu.txt:812: gap of 0.120 s before t = 3.200000 s, integrating across it
/// Thread-safe: lines from different threads never interleave. The sink (stderr by default) is
/// the project's only mutable global.
#include <functional>
#include <sstream>
#include <string>

namespace ltlo::log {

enum class Level { kTrace = 0, kDebug = 1, kInfo = 2, kWarn = 3, kError = 4, kOff = 5 };

/// Lines below `level` are dropped. Default kInfo; LTLO_LOG_LEVEL=trace|debug|info|warn|error|off
/// in the environment overrides the default for programs that call initFromEnvironment().
void setLevel(Level level);
Level level();
void initFromEnvironment();
/// Parses "trace", "debug", "info", "warn", "error", "off"; returns false when unknown.
bool parseLevel(const std::string& text, Level* level);

/// Name printed in front of this thread's lines ("main" unless set).
void setThreadName(const std::string& name);
const std::string& threadName();

void write(Level level, const std::string& message);

/// Receives every finished line ("[thread] level message", no newline) instead of stderr.
/// Called under the logger's lock, one line at a time: it must not log itself.
using Sink = std::function<void(Level level, const std::string& line)>;
/// Installs `sink` (an empty function restores stderr) and returns the previous one. For tests
/// (tests/common/log_capture.h) and front ends; thread-safe.
Sink setSink(Sink sink);

namespace detail {
template <typename... Args>
std::string concat(const Args&... args) {
  std::ostringstream os;
  (os << ... << args);
  return os.str();
}
}  // namespace detail

template <typename... Args>
void trace(const Args&... args) {
  if (level() <= Level::kTrace) write(Level::kTrace, detail::concat(args...));
}
template <typename... Args>
void debug(const Args&... args) {
  if (level() <= Level::kDebug) write(Level::kDebug, detail::concat(args...));
}
template <typename... Args>
void info(const Args&... args) {
  if (level() <= Level::kInfo) write(Level::kInfo, detail::concat(args...));
}
template <typename... Args>
void warn(const Args&... args) {
  if (level() <= Level::kWarn) write(Level::kWarn, detail::concat(args...));
}
template <typename... Args>
void error(const Args&... args) {
  if (level() <= Level::kError) write(Level::kError, detail::concat(args...));
}

}  // namespace ltlo::log
