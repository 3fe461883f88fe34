#pragma once
/// ChangeGate (namespace ltlo): keeps whole-map changes (a loop correction, a merge, the write-back
/// of a full BA) out of the tracking of a frame, and a frame out of a change. Tracking reads the
/// map in the world frame of the frame before: when a correction lands half-way through a frame,
/// the frame's pose is in the old world while its reference keyframe is already in the new one, and
/// the pose kept relative to that keyframe carries the whole correction (ORB-SLAM's map-update
/// mutex has the same role).
///
/// One reader section at a time (the tracking thread) and any number of change sections, which
/// exclude each other and the reader. Changes are preferred: a frame waits while a change is
/// waiting, so a tracker running back to back cannot starve the loop closer. Nothing else is held
/// while waiting here (the outermost lock of the system, see system/system.h).
#include <condition_variable>
#include <mutex>

namespace ltlo {

class ChangeGate {
 public:
  ChangeGate() = default;
  ChangeGate(const ChangeGate&) = delete;
  ChangeGate& operator=(const ChangeGate&) = delete;

  /// Tracking of one frame: waits while a change runs or waits.
  void beginTracking() {
    std::unique_lock<std::mutex> lock(mutex_);
    ++tracking_waiting_;
    cv_.wait(lock, [this] { return !changing_ && changes_waiting_ == 0; });
    --tracking_waiting_;
    tracking_ = true;
  }
  void endTracking() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      tracking_ = false;
    }
    cv_.notify_all();
  }
  /// A change: waits for the frame being tracked and any other change.
  void beginChange() {
    std::unique_lock<std::mutex> lock(mutex_);
    ++changes_waiting_;
    cv_.wait(lock, [this] { return !tracking_ && !changing_; });
    --changes_waiting_;
    changing_ = true;
  }
  void endChange() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      changing_ = false;
    }
    cv_.notify_all();
  }

  /// For tests: sections waiting to begin.
  int changesWaiting() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return changes_waiting_;
  }
  int trackingWaiting() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return tracking_waiting_;
  }

 private:
  mutable std::mutex mutex_;  ///< guards the four fields
  std::condition_variable cv_;
  bool tracking_ = false;
  bool changing_ = false;
  int changes_waiting_ = 0;
  int tracking_waiting_ = 0;
};

/// Scoped sections of a ChangeGate.
class TrackingSection {
 public:
  explicit TrackingSection(ChangeGate& gate) : gate_(gate) { gate_.beginTracking(); }
  TrackingSection(const TrackingSection&) = delete;
  TrackingSection& operator=(const TrackingSection&) = delete;
  ~TrackingSection() { gate_.endTracking(); }

 private:
  ChangeGate& gate_;
};

}  // namespace ltlo
