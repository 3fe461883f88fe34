#pragma once
/// Stage timing for run summaries and metrics.json (STYLE.md section 8): a cheap, always-compiled
/// ScopedTimer feeding a TimingStats that keeps every duration per stage and reports count, mean,
/// median, p95 and max.
///
///   TimingStats timing;                          // owned by System, shared by reference
///   { ScopedTimer t(timing, "tracking.orb"); extractOrb(frame); }   // adds one duration
///   log::info(timing.summary());
///
/// Cost: one steady_clock read at each end and one short mutex-guarded push_back; memory grows by
/// 8 bytes per recorded duration (about 1 MB for 10 stages over 10^4 frames).
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace ltlo {

/// Percentile of `values` (fraction in [0, 1]) with linear interpolation between order
/// statistics: position fraction * (n - 1) in the sorted values (numpy's default). 0 when empty.
double percentile(std::vector<double> values, double fraction);

/// Summary of one stage's recorded durations (seconds).
struct StageTiming {
  std::string stage;
  std::size_t count = 0;
  double total_s = 0.0;
  double mean_s = 0.0;
  double median_s = 0.0;
  double p95_s = 0.0;
  double max_s = 0.0;
};

/// Durations per named stage. Thread-safe: add() may be called from every thread.
class TimingStats {
 public:
  /// Records one duration (seconds, >= 0) for `stage`.
  void add(const std::string& stage, double duration_s);
  /// Statistics of one stage; count == 0 when the stage was never recorded.
  StageTiming stage(const std::string& stage) const;
  /// Statistics of every recorded stage, sorted by stage name.
  std::vector<StageTiming> stages() const;
  /// Multi-line table, one line per stage: "<stage> n=<count> mean=.. median=.. p95=.. max=.. ms".
  std::string summary() const;
  /// JSON object {"<stage>": {"count": n, "mean_ms": .., "median_ms": .., "p95_ms": .., "max_ms":
  /// .., "total_s": ..}, ...} for metrics.json.
  std::string toJson() const;
  void clear();

 private:
  mutable std::mutex mutex_;  // guards durations_
  std::map<std::string, std::vector<double>> durations_s_;
};

/// Measures from construction to stop() (or destruction) and adds the duration to `stats` once.
/// `stage` must outlive the timer (a string literal in practice).
class ScopedTimer {
 public:
  ScopedTimer(TimingStats& stats, const char* stage)
      : stats_(&stats), stage_(stage), start_(std::chrono::steady_clock::now()) {}
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;
  ~ScopedTimer() { stop(); }

  /// Seconds since construction.
  double elapsedS() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  /// Records the duration now; later calls and the destructor do nothing. Returns the duration.
  double stop() {
    if (stats_ == nullptr) return 0.0;
    const double duration_s = elapsedS();
    stats_->add(stage_, duration_s);
    stats_ = nullptr;
    return duration_s;
  }

 private:
  TimingStats* stats_;  // not owned; nullptr once recorded
  const char* stage_;
  std::chrono::steady_clock::time_point start_;
};

/// CPU time of the calling thread, s (CLOCK_THREAD_CPUTIME_ID): what a stage costs, whatever
/// else the machine is running (wall-clock stages inflate when other processes share the cores).
double threadCpuTimeS();

/// Like ScopedTimer, but records the calling thread's CPU time between construction and stop().
/// Stage names end in "_cpu" by convention ("tracking.dense_cpu").
class ScopedThreadCpuTimer {
 public:
  ScopedThreadCpuTimer(TimingStats& stats, const char* stage) : stats_(&stats), stage_(stage), start_s_(threadCpuTimeS()) {}
  ScopedThreadCpuTimer(const ScopedThreadCpuTimer&) = delete;
  ScopedThreadCpuTimer& operator=(const ScopedThreadCpuTimer&) = delete;
  ~ScopedThreadCpuTimer() { stop(); }
  /// Records the CPU time now; later calls and the destructor do nothing. Returns it.
  double stop() {
    if (stats_ == nullptr) return 0.0;
    const double duration_s = std::max(0.0, threadCpuTimeS() - start_s_);
    stats_->add(stage_, duration_s);
    stats_ = nullptr;
    return duration_s;
  }

 private:
  TimingStats* stats_;  // not owned; nullptr once recorded
  const char* stage_;
  double start_s_;
};

}  // namespace ltlo
