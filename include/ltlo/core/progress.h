#pragma once
/// Progress of a long run (STYLE.md section 8): frames done / total, FPS and ETA.
/// On a terminal (stderr is a tty) one line is redrawn in place with '\r'; otherwise (CI logs,
/// files) a plain log line is written every N frames. finish() writes a one-line summary.
///
///   ProgressReporter progress({"frames", static_cast<long>(sequence.size())});
///   for (...) { track(frame); progress.frameDone(); }
///   progress.finish();              // "frames: 500 in 27.3 s (18.3 fps)"
///
/// Thread-safe (one mutex); normally driven by the one thread that consumes the frames.
#include <functional>
#include <mutex>
#include <string>

namespace ltlo {

/// Snapshot of a run's progress. total_frames <= 0 means unknown (no percentage, no ETA).
struct ProgressStatus {
  long frames_done = 0;
  long total_frames = 0;
  double elapsed_s = 0.0;
  double fps = 0.0;     ///< frames_done / elapsed_s (0 before any time has passed)
  double eta_s = -1.0;  ///< remaining frames / fps; < 0 when unknown
};

class ProgressReporter {
 public:
  enum class Style {
    kAuto,      ///< kTerminal when stderr is a terminal (isatty), kLines otherwise
    kTerminal,  ///< one line redrawn in place ("\r...") at most every terminal_refresh_s
    kLines,     ///< a log::info line every log_every_n_frames frames
    kSilent,    ///< nothing until finish()'s summary
  };
  struct Options {
    std::string label = "frames";  ///< what is counted, first word of every line
    long total_frames = 0;         ///< <= 0 when unknown
    Style style = Style::kAuto;
    long log_every_n_frames = 100;    ///< kLines: one line per this many frames
    double terminal_refresh_s = 0.2;  ///< kTerminal: minimum time between redraws (s)
  };
  /// Monotonic time source in seconds (steady_clock by default; tests feed their own).
  using Clock = std::function<double()>;
  /// Receives each line without newline; `in_place` marks a terminal redraw of the same line.
  using Writer = std::function<void(const std::string& line, bool in_place)>;

  /// Real clock; redraws go to stderr, lines and the summary through log::info.
  explicit ProgressReporter(Options options);
  /// Injected clock and writer (tests, or a GUI). kAuto is resolved as kLines here.
  ProgressReporter(Options options, Clock clock, Writer writer);
  ProgressReporter(const ProgressReporter&) = delete;
  ProgressReporter& operator=(const ProgressReporter&) = delete;
  /// Writes the summary if finish() was not called.
  ~ProgressReporter();

  /// Counts `frames` more frames done and writes progress when due.
  void frameDone(long frames = 1);
  ProgressStatus status() const;
  /// Writes and returns the summary line; later calls return it again without writing.
  std::string finish();

  Style style() const { return style_; }

  /// "frames 120/500 (24.0%) | 18.3 fps | elapsed 6.6 s | ETA 20.8 s" (without total:
  /// "frames 120 | 18.3 fps | elapsed 6.6 s").
  static std::string formatStatus(const std::string& label, const ProgressStatus& status);
  /// "4.2 s" below a minute, "3m07s" below an hour, "2h05m" above.
  static std::string formatDuration(double seconds);

 private:
  ProgressStatus statusLocked() const;

  const Options options_;
  Style style_;
  Clock clock_;
  Writer writer_;
  const double start_s_;
  mutable std::mutex mutex_;  // guards everything below and serialises writes
  long frames_done_ = 0;
  double last_redraw_s_ = -1e300;
  bool finished_ = false;
  std::string summary_;
};

}  // namespace ltlo
