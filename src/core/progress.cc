#include "ltlo/core/progress.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "ltlo/core/log.h"

namespace ltlo {
namespace {

double steadyNowS() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Redraws go straight to stderr (no thread prefix, no newline); "\x1b[K" clears what a longer
// previous line left behind. Lines and the summary go through the logger like every other line;
// a newline first ends a redrawn line so the log line starts on its own.
ProgressReporter::Writer stderrWriter() {
  return [showing_line = false](const std::string& line, bool in_place) mutable {
    if (in_place) {
      const std::string text = "\r" + line + "\x1b[K";
      std::fwrite(text.data(), 1, text.size(), stderr);
      std::fflush(stderr);
      showing_line = true;
      return;
    }
    if (showing_line) {
      std::fputc('\n', stderr);
      showing_line = false;
    }
    log::info(line);
  };
}

ProgressReporter::Style resolve(ProgressReporter::Style style, bool can_detect_terminal) {
  if (style != ProgressReporter::Style::kAuto) return style;
  if (can_detect_terminal && isatty(fileno(stderr)) != 0) return ProgressReporter::Style::kTerminal;
  return ProgressReporter::Style::kLines;
}

}  // namespace

ProgressReporter::ProgressReporter(Options options)
    : options_(std::move(options)),
      style_(resolve(options_.style, true)),
      clock_(steadyNowS),
      writer_(stderrWriter()),
      start_s_(clock_()) {}

ProgressReporter::ProgressReporter(Options options, Clock clock, Writer writer)
    : options_(std::move(options)),
      style_(resolve(options_.style, false)),
      clock_(std::move(clock)),
      writer_(std::move(writer)),
      start_s_(clock_()) {}

ProgressReporter::~ProgressReporter() { finish(); }

ProgressStatus ProgressReporter::statusLocked() const {
  ProgressStatus s;
  s.frames_done = frames_done_;
  s.total_frames = options_.total_frames;
  s.elapsed_s = std::max(0.0, clock_() - start_s_);
  s.fps = s.elapsed_s > 0.0 ? static_cast<double>(frames_done_) / s.elapsed_s : 0.0;
  if (s.total_frames > 0 && s.fps > 0.0) {
    s.eta_s = static_cast<double>(std::max(0L, s.total_frames - frames_done_)) / s.fps;
  }
  return s;
}

ProgressStatus ProgressReporter::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return statusLocked();
}

void ProgressReporter::frameDone(long frames) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return;
  const long before = frames_done_;
  frames_done_ += frames;
  switch (style_) {
    case Style::kTerminal: {
      const ProgressStatus s = statusLocked();
      const bool last = s.total_frames > 0 && frames_done_ >= s.total_frames;
      const double now_s = start_s_ + s.elapsed_s;
      if (last || now_s - last_redraw_s_ >= options_.terminal_refresh_s) {
        last_redraw_s_ = now_s;
        writer_(formatStatus(options_.label, s), true);
      }
      break;
    }
    case Style::kLines: {
      const long every = std::max(1L, options_.log_every_n_frames);
      if (frames_done_ / every != before / every)
        writer_(formatStatus(options_.label, statusLocked()), false);
      break;
    }
    case Style::kAuto:  // resolved in the constructor
    case Style::kSilent:
      break;
  }
}

std::string ProgressReporter::finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return summary_;
  finished_ = true;
  const ProgressStatus s = statusLocked();
  std::ostringstream os;
  os << options_.label << ": " << s.frames_done;
  if (s.total_frames > 0 && s.frames_done != s.total_frames) os << " of " << s.total_frames;
  os << " in " << formatDuration(s.elapsed_s);
  char fps[32];
  std::snprintf(fps, sizeof(fps), "%.1f", s.fps);
  os << " (" << fps << " fps)";
  summary_ = os.str();
  writer_(summary_, false);
  return summary_;
}

std::string ProgressReporter::formatDuration(double seconds) {
  char text[32];
  if (!(seconds >= 0.0)) return "?";
  if (seconds < 59.95) {
    std::snprintf(text, sizeof(text), "%.1f s", seconds);
  } else if (seconds < 3600.0 - 0.5) {
    const long total = std::lround(seconds);
    std::snprintf(text, sizeof(text), "%ldm%02lds", total / 60, total % 60);
  } else {
    const long minutes = std::lround(seconds / 60.0);
    std::snprintf(text, sizeof(text), "%ldh%02ldm", minutes / 60, minutes % 60);
  }
  return text;
}

std::string ProgressReporter::formatStatus(const std::string& label, const ProgressStatus& s) {
  std::ostringstream os;
  os << label << " " << s.frames_done;
  char buffer[64];
  if (s.total_frames > 0) {
    std::snprintf(buffer, sizeof(buffer), "/%ld (%.1f%%)", s.total_frames,
                  100.0 * static_cast<double>(s.frames_done) / static_cast<double>(s.total_frames));
    os << buffer;
  }
  std::snprintf(buffer, sizeof(buffer), " | %.1f fps | elapsed ", s.fps);
  os << buffer << formatDuration(s.elapsed_s);
  if (s.total_frames > 0) os << " | ETA " << (s.eta_s >= 0.0 ? formatDuration(s.eta_s) : "?");
  return os.str();
}

}  // namespace ltlo
