#pragma once
// LoopCloser's state (private to ltlo_loop): shared by the closer's processing (loop_closer.cc) and
// its run state in the atlas file (loop_closer_state.cc).
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "ltlo/core/blocking_queue.h"
#include "ltlo/loop/loop_closer.h"
#include "ltlo/loop/loop_corrector.h"
#include "ltlo/loop/loop_detector.h"
#include "ltlo/map/keyframe_database.h"

namespace ltlo::loop {

/// Keyframes processed after a correction or merge before the next loop may be closed (ORB-SLAM
/// waits 10 keyframes: the place just closed is still consistent for the next queries).
inline constexpr int kKeyFramesBetweenLoops = 10;
/// Best covisibles forming a candidate's group (consistency) and setting the BoW score threshold.
inline constexpr std::size_t kGroupSize = 10;

struct LoopCloser::Impl {
  Impl(map::Atlas& atlas_in, const LoopCloserOptions& options_in, MappingControl mapping_in, TimingStats* timing_in)
      : atlas(atlas_in),
        options(options_in),
        mapping(std::move(mapping_in)),
        timing(timing_in),
        queue(options_in.queue_capacity),
        detector(options_in.loop, map::PlaceQueryOptions(), kGroupSize),
        merge_consistency(options_in.loop.min_consistency) {}

  // ---- loop thread (or the caller of processKeyFrame) ----
  void process(const std::shared_ptr<map::KeyFrame>& kf);
  /// Detection, verification and correction in kf's map; true when a loop was closed.
  bool tryLoop(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map);
  /// Loop.MaxCorrectionShare: whether a verified BoW loop's correction is within the drift the map
  /// may have gathered between its two keyframes (always, without gravity or with the share 0).
  bool plausibleCorrection(const map::KeyFrame& kf, const map::KeyFrame& candidate, const LoopClosure& loop,
                           const map::Map& map) const;
  /// Loop.Proximity: the guided search of kf's old, non-covisible neighbours in its own map
  /// (gravity known); true when a loop was closed.
  bool tryProximityLoop(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map);
  /// The correction of an accepted loop (local mapping paused), the event, the full BA.
  bool correct(const std::shared_ptr<map::KeyFrame>& kf, const std::shared_ptr<map::KeyFrame>& candidate,
               const LoopClosure& loop, map::Map& map, bool proximity);
  /// Merge detection against the other maps; true when kf's map was merged.
  bool tryMerge(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map);
  /// Loop.Rejoin: kf's map started at an IMU prediction in its parent's world (map::MapOrigin);
  /// the parent's points around kf's pose, searched within the origin's uncertainty; true when
  /// kf's map was merged into the parent.
  bool tryRejoin(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map);
  /// The guided search settings for kf (Loop.Rejoin's, refined pose) at the given sigmas.
  place::GuidedPlaceMatchOptions guidedSearch(const map::KeyFrame& kf, double sigma_position_m,
                                              double sigma_rotation_rad, std::uint32_t salt) const;
  /// One rejoin search of kf (of `map`) in `target` with the given sigmas; merges on success.
  bool rejoinAt(const std::shared_ptr<map::KeyFrame>& kf, map::Map& map, map::Map& target, double sigma_position_m,
                double sigma_rotation_rad);
  /// The merge of kf's map into `accepted`'s, at `place` when given (else verified by BoW
  /// matching), with local mapping paused, then the event, the detection reset and the full BA.
  bool merge(const std::shared_ptr<map::KeyFrame>& kf, const std::shared_ptr<map::KeyFrame>& accepted,
             std::optional<LoopClosure> place);
  /// Forgets the consistency state (a correction or a map change).
  void resetDetection();
  void recordEvent(const LoopEvent& event);
  /// Arms the refining full BA of `map` after a correction (Loop.RefineKeyFrames).
  void scheduleRefinement(const map::Map& map);
  /// Runs the armed refining (or waiting) full BA once Loop.RefineKeyFrames keyframes of its map
  /// followed the correction and Loop.FullBaBudget allows it.
  void refineAfterCorrection(const std::shared_ptr<map::KeyFrame>& kf);
  /// Whether Loop.FullBaBudget has room for a full BA of `map` now.
  bool fullBaFits(const map::Map& map) const;
  /// Starts the full BA of `map` and counts it against the budget.
  void startBudgetedGlobalBa(map::Map& map, const std::optional<Vec3>& g_w);

  // ---- full BA ----
  /// The IMU's gravity once initialised (nullopt before).
  std::optional<Vec3> gravity() const { return mapping.gravity_w ? mapping.gravity_w() : std::nullopt; }
  /// Starts the full BA of `map` (in its own thread from run(), else synchronously), visual-inertial
  /// with g_w.
  void startGlobalBa(map::Map& map, const std::optional<Vec3>& g_w);
  /// Aborts a running full BA and joins its thread (before any correction writes the map).
  void abortGlobalBa();
  /// Joins the full-BA thread without aborting it.
  void joinGlobalBa();
  void globalBa(map::Map& map, const std::optional<Vec3>& g_w);

  map::Atlas& atlas;
  const LoopCloserOptions options;
  const MappingControl mapping;
  TimingStats* const timing;

  BlockingQueue<std::shared_ptr<map::KeyFrame>> queue;
  std::atomic<bool> in_run{false};  ///< run() is processing: the full BA goes to its own thread

  // Owned by the thread that processes keyframes (the loop thread).
  LoopDetector detector;
  ConsistencyChecker merge_consistency;
  map::MapId detection_map;  ///< map of the last query (the consistency state belongs to it)
  int keyframes_since_correction = kKeyFramesBetweenLoops;
  /// The map whose last correction still waits for its refining full BA (Loop.RefineKeyFrames).
  map::MapId refine_map;
  bool refine_pending = false;
  /// Loop.FullBaBudget: keyframes received, and the full BAs' keyframes counted against them.
  std::uint64_t keyframes_received = 0;
  std::uint64_t full_ba_keyframes = 0;

  // Full BA: the thread object is touched by the loop thread (start/abort) and run()/destructor.
  std::thread ba_thread;
  std::atomic<bool> ba_stop{false};
  mutable std::mutex ba_mutex;  ///< guards ba_running
  std::condition_variable ba_done;
  bool ba_running = false;

  mutable std::mutex events_mutex;  ///< guards events and the counters
  std::vector<LoopEvent> events;
  int num_loops = 0;
  int num_merges = 0;
};

}  // namespace ltlo::loop
