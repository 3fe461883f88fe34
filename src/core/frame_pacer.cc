#include "ltlo/core/frame_pacer.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <utility>

namespace ltlo {

namespace {

double steadySeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

FramePacer::FramePacer(double rate) : FramePacer(rate, steadySeconds) {}

FramePacer::FramePacer(double rate, Clock clock) : rate_(rate), clock_(std::move(clock)) {}

double FramePacer::secondsUntilDue(double t_s) {
  if (!enabled()) return 0.0;
  const double now = clock_();
  if (!anchored_) {
    anchored_ = true;
    anchor_wall_s_ = now;
    anchor_t_s_ = t_s;
    previous_t_s_ = t_s;
  }
  due_wall_s_ = anchor_wall_s_ + (t_s - anchor_t_s_) / rate_;
  interval_wall_s_ = std::max(0.0, t_s - previous_t_s_) / rate_;
  previous_t_s_ = t_s;
  return std::max(0.0, due_wall_s_ - now);
}

double FramePacer::frameStarts() {
  if (!enabled() || !anchored_) return 0.0;
  const double lag_s = std::max(0.0, clock_() - due_wall_s_);
  ++frames_;
  lag_sum_s_ += lag_s;
  max_lag_s_ = std::max(max_lag_s_, lag_s);
  // The first frame has no interval; a frame is late once the next one would already be waiting.
  last_late_ = frames_ > 1 && lag_s > interval_wall_s_;
  late_frames_ += last_late_;
  return lag_s;
}

FramePacerStats FramePacer::stats() const {
  FramePacerStats stats;
  stats.frames = frames_;
  stats.late_frames = late_frames_;
  stats.mean_lag_s = frames_ > 0 ? lag_sum_s_ / static_cast<double>(frames_) : 0.0;
  stats.max_lag_s = max_lag_s_;
  return stats;
}

std::string FramePacer::summary() const {
  if (!enabled()) return "";
  const FramePacerStats s = stats();
  char text[256];
  std::snprintf(text, sizeof(text),
                "real time x%g: %ld frames, %ld (%.1f %%) started more than a frame interval late, lag mean %.1f ms, "
                "max %.1f ms",
                rate_, s.frames, s.late_frames, s.frames > 0 ? 100.0 * s.late_frames / s.frames : 0.0,
                1e3 * s.mean_lag_s, 1e3 * s.max_lag_s);
  return text;
}

}  // namespace ltlo
