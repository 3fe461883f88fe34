#include "ltlo/core/timing.h"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "ltlo/core/assert.h"

namespace ltlo {

double percentile(std::vector<double> values, double fraction) {
  LTLO_ASSERT(fraction >= 0.0 && fraction <= 1.0,
              "percentile fraction " << fraction << " not in [0, 1]");
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double position = fraction * static_cast<double>(values.size() - 1);
  const std::size_t below = static_cast<std::size_t>(std::floor(position));
  const std::size_t above = std::min(below + 1, values.size() - 1);
  const double weight = position - static_cast<double>(below);
  return (1.0 - weight) * values[below] + weight * values[above];
}

namespace {

StageTiming summarise(const std::string& stage, const std::vector<double>& durations_s) {
  StageTiming timing;
  timing.stage = stage;
  timing.count = durations_s.size();
  if (durations_s.empty()) return timing;
  for (const double d : durations_s) {
    timing.total_s += d;
    timing.max_s = std::max(timing.max_s, d);
  }
  timing.mean_s = timing.total_s / static_cast<double>(durations_s.size());
  timing.median_s = percentile(durations_s, 0.5);
  timing.p95_s = percentile(durations_s, 0.95);
  return timing;
}

// Stage names are code identifiers ("tracking.orb"); escape the two JSON specials anyway.
std::string jsonString(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

}  // namespace

void TimingStats::add(const std::string& stage, double duration_s) {
  LTLO_ASSERT(
      duration_s >= 0.0 && std::isfinite(duration_s),
      "stage " << stage << ": duration " << duration_s << " s is not a finite non-negative time");
  std::lock_guard<std::mutex> lock(mutex_);
  durations_s_[stage].push_back(duration_s);
}

StageTiming TimingStats::stage(const std::string& stage) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = durations_s_.find(stage);
  return it == durations_s_.end() ? summarise(stage, {}) : summarise(stage, it->second);
}

std::vector<StageTiming> TimingStats::stages() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<StageTiming> all;
  all.reserve(durations_s_.size());
  for (const auto& [stage, durations] : durations_s_) all.push_back(summarise(stage, durations));
  return all;
}

std::string TimingStats::summary() const {
  std::ostringstream os;
  os << std::fixed << std::setprecision(3);
  bool first = true;
  for (const StageTiming& t : stages()) {
    if (!first) os << "\n";
    first = false;
    os << t.stage << " n=" << t.count << " mean=" << 1e3 * t.mean_s
       << " median=" << 1e3 * t.median_s << " p95=" << 1e3 * t.p95_s << " max=" << 1e3 * t.max_s
       << " ms";
  }
  return os.str();
}

std::string TimingStats::toJson() const {
  std::ostringstream os;
  os << std::setprecision(6);
  os << "{";
  bool first = true;
  for (const StageTiming& t : stages()) {
    os << (first ? "" : ", ") << jsonString(t.stage) << ": {\"count\": " << t.count
       << ", \"mean_ms\": " << 1e3 * t.mean_s << ", \"median_ms\": " << 1e3 * t.median_s
       << ", \"p95_ms\": " << 1e3 * t.p95_s << ", \"max_ms\": " << 1e3 * t.max_s
       << ", \"total_s\": " << t.total_s << "}";
    first = false;
  }
  os << "}";
  return os.str();
}

void TimingStats::clear() {
  std::lock_guard<std::mutex> lock(mutex_);
  durations_s_.clear();
}

double threadCpuTimeS() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

}  // namespace ltlo
