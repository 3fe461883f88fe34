#include "ltlo/core/log.h"

#include <pthread.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <utility>

#include "ltlo/core/thread_names.h"

namespace ltlo::log {
namespace {

std::atomic<Level> g_level{Level::kInfo};
std::mutex g_sink_mutex;  // guards g_sink and stderr writes so lines do not interleave
Sink g_sink;              // empty: stderr

std::string& threadNameStorage() {
  thread_local std::string name = "main";
  return name;
}

const char* levelName(Level level) {
  switch (level) {
    case Level::kTrace: return "trace";
    case Level::kDebug: return "debug";
    case Level::kInfo: return "info";
    case Level::kWarn: return "warn";
    case Level::kError: return "error";
    case Level::kOff: return "off";
  }
  return "?";
}

}  // namespace

void setLevel(Level level) { g_level.store(level); }
Level level() { return g_level.load(std::memory_order_relaxed); }

bool parseLevel(const std::string& text, Level* level) {
  static const std::pair<const char*, Level> kNames[] = {
      {"trace", Level::kTrace}, {"debug", Level::kDebug}, {"info", Level::kInfo},
      {"warn", Level::kWarn},   {"error", Level::kError}, {"off", Level::kOff}};
  for (const auto& [name, value] : kNames) {
    if (text == name) {
      *level = value;
      return true;
    }
  }
  return false;
}

void initFromEnvironment() {
  const char* env = std::getenv("LTLO_LOG_LEVEL");
  Level parsed;
  if (env != nullptr && parseLevel(env, &parsed)) setLevel(parsed);
}

void setThreadName(const std::string& name) {
  threadNameStorage() = name;
#ifdef __linux__
  // Also the OS name (ltlo/core/thread_names.h); the main thread keeps its OS name: it is the
  // process name ps and top show.
  if (static_cast<pid_t>(syscall(SYS_gettid)) != getpid()) {
    const std::string os_name = (std::string(kThreadNamePrefix) + name).substr(0, 15);
    pthread_setname_np(pthread_self(), os_name.c_str());
    ltlo::detail::registerNamedThread(os_name);
  }
#endif
}

const std::string& threadName() { return threadNameStorage(); }

void write(Level level, const std::string& message) {
  const std::string line = "[" + threadName() + "] " + levelName(level) + " " + message + "\n";
  std::lock_guard<std::mutex> lock(g_sink_mutex);
  if (g_sink) {
    g_sink(level, line.substr(0, line.size() - 1));
    return;
  }
  std::fwrite(line.data(), 1, line.size(), stderr);
  std::fflush(stderr);
}

Sink setSink(Sink sink) {
  std::lock_guard<std::mutex> lock(g_sink_mutex);
  std::swap(sink, g_sink);
  return sink;
}

}  // namespace ltlo::log
