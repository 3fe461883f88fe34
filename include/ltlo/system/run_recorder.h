#pragma once
/// RunRecorder (namespace ltlo::system): the bookkeeping of one run, owned by System. It keeps a
/// record of every frame with a pose (its reference keyframe and the camera relative to it, the pose
/// tracking returned, the IMU-carried stretches), the run's frame counters, the colours of every
/// keyframe's keypoints, and assembles from them and the Atlas the run's results (run_records.h):
/// the final trajectory (loop corrections, merges and the smoothing of carried stretches included),
/// the online trajectory, the keyframes, the coloured map points and the counts.
///
/// Threads and locks:
///   tracking thread (System::trackFrame and the Tracker's keyframe callback inside it) writes:
///     recordKeyFrameColours, recordFrame. The counters and the open carried stretch are
///     tracking-thread state without a lock; numFrames and counts read them and are called from
///     the tracking thread only (System::counts, System::report, the viewer's frame index).
///   any thread (the caller's result accessors, the viewer thread through System::viewerMap) reads:
///     trajectory, onlineTrajectory, framePositionsInMap, keyFrames, mapPoints.
/// mutex_ guards the frame records and the keyframe colours and nothing else. It is a leaf lock
/// (below the lock order of ltlo/map/atlas.h): never held while calling into the map, a queue or a
/// stage; the readers copy under it and read keyframes and map points after releasing it, or read
/// the map first and take it afterwards.
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/map/ids.h"
#include "ltlo/system/carried_stretch.h"
#include "ltlo/system/run_records.h"

namespace ltlo {
class Undistorter;
}
namespace ltlo::map {
class Atlas;
class ByteReader;
class ByteWriter;
class Frame;
class KeyFrame;
class KeyFrameRefs;
class RunKeyFrames;
}  // namespace ltlo::map
namespace ltlo::loop {
class LoopCloser;
}
namespace ltlo::tracking {
class Tracker;
}

namespace ltlo::system {

/// What recordFrame stored of a frame with a pose (for the viewer's status).
struct RecordedFrame {
  bool tracked = false;  ///< tracked against the map
  bool carried = false;  ///< posed by the IMU's prediction alone
  map::MapId map;        ///< the map the frame was tracked in
};

class RunRecorder {
 public:
  /// Reads the Atlas through its thread-safe API; `tracking` gives Tracking.MinInliers (the weak-IMU
  /// count) and the smoothing of carried stretches (Tracking.CarriedVelocitySigma, Tracking.AccBiasSigma).
  RunRecorder(map::Atlas& atlas, const TrackingOptions& tracking);
  RunRecorder(const RunRecorder&) = delete;
  RunRecorder& operator=(const RunRecorder&) = delete;

  /// Tracking thread, when keyframe `kf` is created from the frame of `color_bgr`: the BGR colour
  /// of every keypoint (sampled in the raw image through `undistorter`). Takes mutex_.
  void recordKeyFrameColours(const map::KeyFrame& kf, const cv::Mat& color_bgr, const Undistorter& undistorter);
  /// Tracking thread, once per frame after Tracker::track (inside the tracking section): counts the
  /// frame and, when it has a pose, stores its record (reference keyframe, online pose, carried
  /// stretch) and counts the loss policy's outcome from `tracker`'s state. Takes mutex_ to store.
  /// Returns what was stored, nullopt for a frame without a pose.
  std::optional<RecordedFrame> recordFrame(double t_s, const map::Frame& frame, const tracking::Tracker& tracker);

  /// Tracking thread: frames given to recordFrame.
  int numFrames() const { return frames_; }
  /// Time of the first frame with a pose (NaN: none yet). Takes mutex_.
  double firstPoseTime() const;
  /// Tracking thread (it owns `tracker`): the run's counts, from the frame counters here, the Atlas,
  /// the tracker (maps created, IMU initialised) and the loop closer (loops, merges). Takes mutex_.
  SystemCounts counts(const tracking::Tracker& tracker, const loop::LoopCloser& closer) const;

  /// Tracking thread (recordFrame, every kReleaseEveryFrames frames; System::shutdown): the culled
  /// keyframes the records hold (as reference, as stretch reference, the open stretch's) are swapped
  /// for their stand-ins (map::culledStandIn), and the stand-ins' culled parents for theirs once those
  /// are culled too; the colours of the swapped keyframes are dropped. A culled keyframe's image data
  /// is then freed once the stages let go of it: held by the records, a run of many laps kept every
  /// keyframe it ever made (issue 32). The trajectories are the same to the bit (a stand-in walks the
  /// same chain). Stand-ins are made outside mutex_ (a leaf lock; keyframes have their own) and
  /// swapped in under it.
  void releaseCulledKeyFrames();

  /// Any thread. Every frame with a pose, in input order, from its reference keyframe's latest pose;
  /// IMU-carried stretches corrected as `correction` says (system/carried_stretch.h).
  std::vector<FramePose> trajectory(CarriedCorrection correction) const;
  /// Any thread. Every frame with a pose, in input order, as tracking returned it at that frame.
  std::vector<FramePose> onlineTrajectory() const;
  /// Any thread. The camera centres of the frames whose reference keyframe is in map `map_id` now,
  /// in input order, from the keyframes' latest poses (the viewer's trajectory).
  std::vector<Eigen::Vector3f> framePositionsInMap(map::MapId map_id) const;
  /// Any thread. Live keyframes of every map, by time (reads the Atlas only).
  std::vector<KeyFrameRecord> keyFrames() const;
  /// Any thread. Map points of the active map with beta and the colour of their first observation
  /// with a recorded colour (reference keyframe first). Reads the map, then takes mutex_.
  std::vector<MapPointRecord> mapPoints() const;

  /// Tracking thread, for a run resumed from an atlas file (system/run_state.h): every frame record
  /// (the final trajectory's carried stretches and floating maps reach across the resumed frame),
  /// with the IMU data kept for the inertial bridge, the open carried stretch, the frames held back
  /// in case a stretch follows (CarriedImuRetention's state), the keyframes' colours. The frame counters are statistics and stay
  /// this run's.
  void writeState(map::ByteWriter& out, map::KeyFrameRefs& refs) const;
  /// Restores it before the first frame: the restored records are context, not output (the
  /// trajectories, counts and first pose time are this run's frames'). Throws AtlasFileError.
  void readState(map::ByteReader& in, const map::RunKeyFrames& keyframes);

 private:
  /// Per-frame record: the reference keyframe and the camera relative to its body frame
  /// (T_refb_c = T_w_b(ref)^-1 T_w_c at tracking time), or an absolute pose without one.
  struct FrameRecord {
    double t_s = 0.0;
    std::shared_ptr<const map::KeyFrame> reference;
    SE3 T_refb_c;  ///< with a reference
    SE3 T_w_c;     ///< without one
    bool tracked = false;
    /// posed by the IMU's prediction alone (not tracked; with a reference)
    bool carried = false;
    /// The first frame anchored by vision after a carried stretch: the keyframe the stretch hung
    /// on and this frame's dead-reckoned pose relative to it (system/carried_stretch.h).
    std::shared_ptr<const map::KeyFrame> stretch_reference;
    SE3 T_stretchrefb_c_predicted;
    /// The pose as tracking returned it for this frame (the online stream): never moved by a later
    /// loop correction, merge or smoothing; in the world of `map_online` at that time.
    SE3 T_w_c_online;
    map::MapId map_online;
    /// The frame's IMU data in the world of T_w_c_online, kept for the inertial bridge of carried
    /// stretches (CarriedImuRetention: carried frames and their margins only).
    std::shared_ptr<const CarriedImu> imu;
  };

  /// Tracking thread: the carried-stretch part of `record` (the stretch it ends, the stretch it
  /// opens or continues) from the IMU's prediction of the frame.
  void trackCarriedStretch(FrameRecord& record, const map::Frame& frame, const std::optional<SE3>& predicted_T_w_b);
  /// Tracking thread: the loss policy's outcome counters of a frame with a pose.
  void countLossPolicy(const FrameRecord& record, const tracking::Tracker& tracker);

  /// Tracking thread: the records [first, end) as holding `kf` (the span list of whole keyframes).
  void noteReference(const std::shared_ptr<const map::KeyFrame>& kf, std::size_t record);
  /// The stand-in of culled keyframe `kf`, made once per id.
  std::shared_ptr<map::KeyFrame> standInOf(const map::KeyFrame& kf);
  static constexpr int kReleaseEveryFrames = 30;

  /// The floating maps of the run's records (system/carried_stretch.h, floatingMapWorlds): floating
  /// map -> the map whose world it stands in. A longer map than kFloatingMapMaxSpan_s has tracked
  /// long enough for its own error to differ from the dead reckoning's shape.
  std::unordered_map<map::MapId, map::MapId> floatingMaps(const std::vector<FrameRecord>& records) const;
  static constexpr double kFloatingMapMaxSpan_s = 5.0;
  static constexpr int kFloatingMapMaxDepth = 4;

  map::Atlas& atlas_;
  const TrackingOptions tracking_;

  // Tracking-thread state.
  int frames_ = 0;
  int frames_tracked_ = 0;
  // Outcomes of the loss policy: see SystemCounts.
  int frames_tracked_weak_imu_ = 0;
  int frames_imu_predicted_ = 0;
  int relocalisations_ = 0;
  int maps_extended_ = 0;
  /// The keyframe the open IMU-carried stretch hangs on (null: no stretch open).
  std::shared_ptr<const map::KeyFrame> carried_reference_;
  int reacquisitions_ = 0;
  int frames_before_map_ = 0;
  CarriedImuRetention imu_retention_;
  /// Records of frames dead-reckoned before the first map (Tracking.PreMapImuPose), not yet on a
  /// keyframe: the first record with a reference anchors them to it (same world at that moment), so
  /// that the map's later corrections carry them.
  std::vector<std::size_t> pre_map_records_;
  /// Records [first, end) hold `kf` as reference; only keyframes not yet swapped for a stand-in
  /// (releaseCulledKeyFrames), in record order.
  struct ReferenceSpan {
    std::shared_ptr<const map::KeyFrame> kf;
    std::size_t first = 0;
    std::size_t end = 0;
  };
  std::vector<ReferenceSpan> whole_references_;
  /// Records whose stretch reference is a keyframe not yet swapped.
  std::vector<std::size_t> whole_stretch_records_;
  /// The stand-ins made, by keyframe id; those whose culled parent is not a stand-in.
  std::unordered_map<map::KeyFrameId, std::shared_ptr<map::KeyFrame>> stand_ins_;
  std::vector<std::shared_ptr<map::KeyFrame>> stand_ins_with_whole_parent_;
  int frames_since_release_ = 0;

  mutable std::mutex mutex_;  ///< guards records_, context_records_ and colours_ (leaf lock)
  std::vector<FrameRecord> records_;
  /// The first records_ restored from a saved run (readState): context of the final trajectory,
  /// not output.
  std::size_t context_records_ = 0;
  /// BGR colour of every keypoint of each keyframe, sampled when the keyframe was created.
  std::unordered_map<std::uint64_t, std::vector<cv::Vec3b>> colours_;
};

}  // namespace ltlo::system
