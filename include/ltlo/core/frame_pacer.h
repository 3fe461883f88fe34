#pragma once
/// Plays a recorded sequence at the speed it was recorded (times a rate), as a live camera would
/// deliver it: each frame is due at the wall time its stamp lies after the first frame's, divided
/// by the rate. A frame whose processing starts after it was due is not dropped (a driver's queue
/// holds it); its lag is counted, so a run says whether tracking kept up with the camera.
///
///   FramePacer pacer(1.0);                              // the sequence's own speed
///   for (...) {
///     sleepFor(pacer.secondsUntilDue(frame.t_s));       // 0 when due or late
///     pacer.frameStarts();                              // records the frame's lag
///     track(frame);
///   }
///   log::info(pacer.summary());   // "real time x1: 9000 frames, 3 more than a frame interval late ..."
///
/// Rate 0 (or below) turns pacing off: every frame is due at once and nothing is counted.
/// Not thread-safe: owned by the thread that feeds the frames.
#include <functional>
#include <string>

namespace ltlo {

struct FramePacerStats {
  long frames = 0;           ///< frames started under pacing
  long late_frames = 0;      ///< started more than one frame interval after they were due
  double mean_lag_s = 0.0;   ///< mean of max(0, start - due)
  double max_lag_s = 0.0;
};

class FramePacer {
 public:
  /// Monotonic time source in seconds (steady_clock by default; tests feed their own).
  using Clock = std::function<double()>;

  explicit FramePacer(double rate);
  FramePacer(double rate, Clock clock);

  bool enabled() const { return rate_ > 0.0; }
  double rate() const { return rate_; }

  /// Wall seconds until the frame stamped `t_s` (sequence seconds) is due; 0 when it is due, late or
  /// pacing is off. The first frame asked about anchors the sequence's time to the wall clock.
  double secondsUntilDue(double t_s);
  /// The frame last asked about starts now: records and returns its lag behind its due time (s).
  double frameStarts();
  /// The frame last started began more than its interval from the frame before late.
  bool lastFrameLate() const { return last_late_; }

  FramePacerStats stats() const;
  /// "real time x1: 9000 frames, 12 (0.1 %) started more than a frame interval late, lag mean 1.2 ms,
  /// max 85.0 ms"; "" when pacing is off.
  std::string summary() const;

 private:
  const double rate_;
  Clock clock_;
  bool anchored_ = false;
  double anchor_wall_s_ = 0.0;
  double anchor_t_s_ = 0.0;
  double previous_t_s_ = 0.0;
  double due_wall_s_ = 0.0;      ///< the last asked frame's due time
  double interval_wall_s_ = 0.0;  ///< its wall interval from the frame before (its lateness bound)
  bool last_late_ = false;
  long frames_ = 0;
  long late_frames_ = 0;
  double lag_sum_s_ = 0.0;
  double max_lag_s_ = 0.0;
};

}  // namespace ltlo
