#pragma once
/// System (namespace ltlo::system): the whole SLAM pipeline of one run. It owns the Atlas and the
/// three stages (DESIGN.md "Threads and data flow"):
///   tracking        in the caller's thread (trackFrame): ORB + depth (FrameBuilder) while the
///                   tracker's FrameSegmenter starts on the images (Seg.Enable, Seg.DenseInit pick
///                   it), then Tracker::track (prediction, segmentation, matching, keyframes);
///   local mapping   LocalMapper::run in a thread started here;
///   loop closing    LoopCloser::run in a thread started here (it starts and joins its full-BA
///                   thread itself).
/// Keyframes flow tracking -> local mapping (Tracker callback -> LocalMapper::insertKeyFrame) ->
/// loop closing (LocalMapper callback -> LoopCloser::insertKeyFrame), each through the receiver's
/// bounded queue. Loop closing pauses local mapping around a correction (MappingControl ->
/// LocalMapper::pause/resume) and holds tracking between two frames (world_gate_). The IMU state flows back by polling: every frame the tracker reads
/// LocalMapper::imuState() and takes a new estimate when its generation changes.
///
/// Ownership and locks: System owns the Atlas, the Tracker, the LocalMapper, the LoopCloser, the
/// two std::threads, the RunRecorder (run_recorder.h: the per-run records - frame references,
/// keyframe colours - behind RunRecorder::mutex_, and the frame counters) and, with a viewer output,
/// the ViewerFeed with the viewer thread (system/viewer_feed.h). The map structures follow the lock
/// order of ltlo/map/atlas.h
///   Atlas::mutex_ -> Map::topology_mutex_ -> Map::mutex_ -> KeyFrame::mutex_ -> MapPoint::mutex_;
/// RunRecorder::mutex_ is a leaf: it is never held while calling into the map, a queue or another
/// stage.
/// world_gate_ (core/change_gate.h) is outermost: the tracking thread holds it from Tracker::track
/// until the frame's record is stored, the loop closer while it changes a map's world frame (with
/// local mapping paused first: LocalMapper::pause -> world_gate_). Nothing in the tracking section
/// waits for another stage: its keyframes reach local mapping's queue after the section ends.
/// Threads are started in the constructor (loop closing first, then local mapping) and joined in
/// reverse data-flow order by shutdown(): local mapping first (it drains its queue and hands the
/// last keyframes on), then loop closing (it drains, then waits for a running full BA).
/// Within trackFrame the segmenter may work on the input images in its own worker thread while the
/// tracking thread extracts ORB features; it only reads the input frame and its own buffers and is
/// joined inside Tracker::track (FrameSegmenter::segment) or cancelled on an error.
///
/// With SystemOptions::threaded == false no thread is started: after every keyframe, trackFrame
/// runs LocalMapper::processKeyFrame and LoopCloser::processKeyFrame itself (deterministic; tests).
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "ltlo/core/change_gate.h"
#include "ltlo/core/eigen_types.h"
#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/timing.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/map/atlas_file.h"
#include "ltlo/map/ids.h"
#include "ltlo/mapping/local_mapper.h"
#include "ltlo/system/carried_stretch.h"
#include "ltlo/system/run_records.h"
#include "ltlo/system/run_state.h"
#include "ltlo/tracking/frame_builder.h"
#include "ltlo/tracking/tracker.h"
#include "ltlo/viewer/viewer_state.h"

namespace bow {
class Vocabulary;
}

namespace ltlo::map {
class Atlas;
class KeyFrame;
}  // namespace ltlo::map
namespace ltlo::mapping {
class LocalMapper;
}
namespace ltlo::loop {
class LoopCloser;
}
namespace ltlo::tracking {
class FrameBuilder;
}

namespace ltlo::system {
class RunRecorder;
class SegmentationWriter;
class ViewerFeed;
}

namespace ltlo::system {

struct SystemOptions {
  /// false: RGB-D only (the frames' IMU samples are ignored, no IMU initialisation). The IMU is
  /// also unused when the calibration has none.
  bool use_imu = true;
  /// false: local mapping and loop closing run synchronously inside trackFrame after each keyframe
  /// (deterministic, for tests); true: each in its own thread.
  bool threaded = true;
  /// The --oracle-masks ablation (diagnostic only): every frame's ground-truth mask
  /// (io::RgbdImuFrame::mask, read with SequenceReaderOptions::read_masks) replaces the
  /// segmentation (tracking::OracleMaskSegmenter); the run's metrics record it.
  bool oracle_masks = false;
  /// Folder for every frame's static/dynamic mask (<timestamp>.png, SegmentationWriter); empty:
  /// no masks are written.
  std::string segmentation_dir;
  /// The live viewer's outputs (viewer/viewer.h; video, PNG folder, HTTP stream, pose stream):
  /// with any of them set System starts a viewer thread, stopped last by shutdown().
  std::string viewer_video_path;
  std::string viewer_png_dir;
  int viewer_http_port = -1;
  std::string viewer_http_bind = "127.0.0.1";
  bool viewer_pose_stream = false;
  /// An atlas file saved by an earlier run (map/atlas_file.h): its maps become this run's atlas,
  /// the run starts lost in them and relocalises (Tracking.LoadedAtlasNewMapAfter), and its poses
  /// are in the loaded world frame. Its IMU state seeds this run's. Empty: a new atlas.
  /// Tracking.LocalisationOnly needs one.
  std::string load_atlas_path;
  /// With load_atlas_path: the file's run state (its optional run section, map/run_state_io.h) is
  /// restored as well, and the run goes on from the saved run's last frame (resumePoint) instead of
  /// starting lost: tracker, segmenter, local mapping, loop closing and the records continue as the
  /// saved run would have. The file must have a run state (AtlasFileError naming the section).
  bool resume = false;
};

/// Where a resumed run goes on (System::resumePoint).
struct ResumePoint {
  std::uint64_t next_frame_index = 0;  ///< the sequence index of the resumed run's first frame
  double last_frame_t_s = 0.0;         ///< the saved run's last frame (s): the sequence's frame before
  /// The time of the previous frame whose images restorePreviousFrame needs (the segmenter rebuilds
  /// its pyramid and clusters from them); nullopt when none is needed.
  std::optional<double> previous_frame_t_s;
  /// Earlier frames (s, oldest first) the segmenter keeps as references (Dense.ReferenceBaseline),
  /// rebuilt from their images too: restoreKeptFrame with each, in this order, before
  /// restorePreviousFrame. Empty when none is kept (then previous_frame_t_s may still be set).
  std::vector<double> kept_frame_t_s;
  /// The saved run's settings differed from this run's (the continuation is then not exact).
  bool settings_differ = false;
};

/// Not thread-safe as a whole: one thread (the caller, "tracking") calls trackFrame and shutdown;
/// the result accessors may be called from that thread at any time (they read the map through its
/// thread-safe API) and give the final results after shutdown().
class System {
 public:
  /// `settings.calib` is the sensor calibration of the frames to come. Throws ConfigError on a
  /// calibration the pipeline cannot use.
  System(const Settings& settings, std::shared_ptr<const bow::Vocabulary> vocabulary,
         const SystemOptions& options = {});
  System(const System&) = delete;
  System& operator=(const System&) = delete;
  /// Calls shutdown().
  ~System();

  /// Tracks one frame (caller's thread). Throws InputError when the images do not have the
  /// calibration's size, SystemError when a mapping or loop thread has
  /// stopped on an error (the log names it), std::logic_error after shutdown().
  tracking::TrackingState trackFrame(const io::RgbdImuFrame& input);

  /// Stops and joins local mapping, then loop closing (which waits for its full BA). Idempotent.
  /// `run_finished`: the input ended (false: an interrupt or an error stopped the run); only then the
  /// end-of-run adjustment runs (Loop.FinalFullBa), which an interrupted run should not wait for.
  void shutdown(bool run_finished = true);
  bool isShutDown() const { return shut_down_; }

  /// Every frame with a pose, in input order; IMU-carried stretches corrected as
  /// Tracking.SmoothCarriedFrames and Tracking.CarriedBridge say (system/carried_stretch.h).
  std::vector<FramePose> trajectory() const;
  /// The same, with carried stretches corrected as `correction` says (e.g. as the IMU predicted
  /// them, or the blend and the bridge of one run side by side).
  std::vector<FramePose> trajectory(CarriedCorrection correction) const;
  /// Every frame with a pose, in input order, as tracking returned it at that frame (before any
  /// later loop correction, merge or smoothing): what a controller reading the live pose got.
  /// FramePose::map is the map the frame was tracked in.
  std::vector<FramePose> onlineTrajectory() const;
  /// The active state of map `map_id` (after merges, the map it went into) for the viewer: points
  /// with beta, keyframes with their covisibility (the best 4 of each) and loop edges, the frames
  /// of that map so far. Any thread; reads the map through its thread-safe API (copies).
  viewer::ViewerMap viewerMap(std::uint64_t map_id) const;
  /// Live keyframes of every map, by time.
  std::vector<KeyFrameRecord> keyFrames() const;
  /// Map points of the active map (the map tracking ended in; other maps have their own world
  /// frame) with colour and beta.
  std::vector<MapPointRecord> mapPoints() const;
  SystemCounts counts() const;
  /// Everything above plus the timing and the peak memory (call after shutdown()); `wall_s` is
  /// the caller's measurement of the run.
  RunReport report(double wall_s) const;
  tracking::TrackingState state() const;
  /// Local mapping's IMU estimate (gravity in the map frame, biases; not initialised without the
  /// IMU). Any thread.
  mapping::ImuState imuState() const;

  /// Writes the atlas (every map, keyframe and point, and the IMU state) to `path` (atomic:
  /// written as path.part, then renamed), for a later run's load_atlas_path, with the run state a
  /// resumed run continues from (system/run_state.h; the frame after the last one trackFrame
  /// completed is the next; left out, with a warning, when a frame or a keyframe was left
  /// part-way by an error). Call after shutdown(). Throws InputError naming the file when it
  /// cannot be written.
  void saveAtlas(const std::string& path);

  /// A resumed run (SystemOptions::resume): where it goes on. nullopt otherwise.
  std::optional<ResumePoint> resumePoint() const { return resume_point_; }
  /// A resumed run whose ResumePoint::previous_frame_t_s is set: the images of that frame (the
  /// sequence's frame next_frame_index - 1), from which the segmenter rebuilds its previous frame.
  /// Call before the first trackFrame. Throws InputError when it is another frame.
  void restorePreviousFrame(const io::RgbdImuFrame& previous);
  /// A resumed run whose ResumePoint::kept_frame_t_s is not empty: the images of the next of those
  /// frames (in their order, before restorePreviousFrame). Throws InputError when it is another frame.
  void restoreKeptFrame(const io::RgbdImuFrame& frame);

  /// Stage durations of all threads ("tracking.*", "mapping.*", "loop.*").
  TimingStats& timing() { return timing_; }
  const TimingStats& timing() const { return timing_; }
  const Settings& settings() const { return settings_; }
  bool usesImu() const { return use_imu_; }

 private:
  void onNewKeyFrame(const std::shared_ptr<map::KeyFrame>& kf);  // tracking thread
  void processPendingKeyFrames();                                 // synchronous mode
  void pollImuState();
  void checkWorkers() const;
  /// Replaces atlas_ by the file's (options_.load_atlas_path); returns its IMU state. With
  /// options_.resume it keeps the file's run state in loaded_run_ (restoreRunState applies it).
  map::AtlasImuState loadAtlas();
  /// The stages and System's own state the run section holds (system/run_state.h).
  RunStages runStages();
  std::uint64_t settingsFingerprint() const;
  /// Restores the stages from loaded_run_ and sets resume_point_.
  void restoreRunState();
  /// The vocabulary and the map-relevant settings an atlas file is checked against.
  map::AtlasBuildInfo atlasBuildInfo() const;

  const Settings settings_;
  const SystemOptions options_;
  const std::shared_ptr<const bow::Vocabulary> vocabulary_;
  bool use_imu_ = true;

  TimingStats timing_;
  std::unique_ptr<map::Atlas> atlas_;  // first member built, last destroyed (after the workers)
  /// What the loaded atlas held (SystemOptions::load_atlas_path; atlas_loaded false without one).
  SystemCounts loaded_;
  std::unique_ptr<tracking::FrameBuilder> builder_;
  tracking::ImuShiftRamp imu_shift_;  // tracking thread: each frame's IMU interval against its stamps
  std::unique_ptr<tracking::Tracker> tracker_;
  std::unique_ptr<mapping::LocalMapper> mapper_;
  std::unique_ptr<loop::LoopCloser> closer_;
  std::unique_ptr<SegmentationWriter> segmentation_writer_;  // with SystemOptions::segmentation_dir
  /// With a viewer output: the Viewer and what tracking posts to it (system/viewer_feed.h); reads the
  /// Atlas, stopped last.
  std::unique_ptr<ViewerFeed> viewer_;
  ChangeGate world_gate_;  ///< tracking of a frame vs world-frame changes by loop closing
  std::thread mapping_thread_;
  std::thread loop_thread_;
  std::atomic<bool> finishing_{false};        ///< shutdown() asked the workers to finish
  std::atomic<bool> mapping_stopped_{false};  ///< LocalMapper::run returned
  std::atomic<bool> loop_stopped_{false};     ///< LoopCloser::run returned
  bool shut_down_ = false;

  // Tracking-thread state.
  const io::RgbdImuFrame* current_input_ = nullptr;  ///< during trackFrame (keyframe colours)
  /// Keyframes of the frame being tracked: handed to local mapping after the tracking section (threaded)
  /// or processed after the frame (synchronous mode).
  std::vector<std::shared_ptr<map::KeyFrame>> pending_keyframes_;
  std::uint64_t imu_generation_ = 0;
  /// The last frame trackFrame completed (its sequence index and time), for the saved run state.
  std::optional<std::pair<int, double>> last_input_;
  /// trackFrame began a frame and did not complete it (it threw): the stages are mid-frame and
  /// saveAtlas leaves the run state out.
  bool frame_in_progress_ = false;
  /// A resumed run: the run state read from the file (until applied), and where it goes on.
  std::optional<map::LoadedRunState> loaded_run_;
  std::optional<ResumePoint> resume_point_;
  /// The run's records, counters and results (run_recorder.h); declared last, so destroyed first as
  /// the records were.
  std::unique_ptr<RunRecorder> recorder_;
};

/// A worker thread stopped on an error; the run ends in an orderly shutdown.
class SystemError : public std::runtime_error {
 public:
  explicit SystemError(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace ltlo::system
