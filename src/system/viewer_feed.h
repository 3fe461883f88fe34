#pragma once
/// ViewerFeed (namespace ltlo::system, private to system/): the live viewer of a run
/// (viewer/viewer.h) and what the run hands it. System owns the feed, and through it the Viewer,
/// when SystemOptions asks for a viewer output, and stops it last in shutdown().
///
/// Threads: the tracking thread calls post (every frame with a pose), stop and addCounts; the
/// feed's own members (the loop events seen, the raw -> ideal map of the mask) are tracking-thread
/// state without a lock, the Viewer synchronises its mailbox itself. The viewer thread pulls the
/// map view through the MapSource given at construction (System::viewerMap -> viewerMapOf), which
/// reads the Atlas through its thread-safe API, the loop closer's counts and the RunRecorder's frame
/// positions (RunRecorder::mutex_, a leaf lock) and holds nothing afterwards.
#include <cstdint>
#include <memory>

#include <opencv2/core.hpp>

#include "ltlo/core/settings.h"
#include "ltlo/core/timing.h"
#include "ltlo/map/ids.h"
#include "ltlo/tracking/tracker.h"
#include "ltlo/viewer/viewer.h"

namespace ltlo {
class PinholeCamera;
class Undistorter;
}  // namespace ltlo
namespace ltlo::io {
struct RgbdImuFrame;
}
namespace ltlo::map {
class Atlas;
class Frame;
}  // namespace ltlo::map
namespace ltlo::loop {
class LoopCloser;
}

namespace ltlo::system {

struct RecordedFrame;
struct RunReport;
struct SystemOptions;
class RunRecorder;

class ViewerFeed {
 public:
  /// The viewer outputs SystemOptions asks for (none set: ViewerOutputs::any() is false, no viewer).
  static viewer::ViewerOutputs outputs(const SystemOptions& options);

  /// Opens the outputs and starts the viewer thread (throws what viewer::Viewer throws). `closer`,
  /// `camera` (the calibration's ideal camera), `undistorter` and `timing` outlive the feed.
  ViewerFeed(const ViewerOptions& options, const viewer::ViewerOutputs& outputs, viewer::Viewer::MapSource map_source,
             const loop::LoopCloser& closer, const PinholeCamera& camera, const Undistorter& undistorter,
             TimingStats& timing);

  /// Tracking thread, for frame `index` (input order) with a pose: the pose on the pose stream, a
  /// loop flash when loops or merges grew, and a copy of the frame when the viewer is due (never
  /// waits on it).
  void post(int index, const io::RgbdImuFrame& input, const map::Frame& frame, tracking::TrackingState state,
            const RecordedFrame& recorded);
  /// Renders the frame still waiting and joins the viewer thread (viewer::Viewer::stop). Idempotent.
  void stop();
  /// The viewer's figures of the run: viewer_on and the viewer_* counts.
  void addCounts(RunReport& report) const;

 private:
  /// The picture's inputs of `frame`: the input colour image, the dynamic mask at a quarter of the
  /// input size and the keypoints with their classes, on the raw image.
  viewer::ViewerFrame pictureOf(int frame_index, const io::RgbdImuFrame& input, const map::Frame& frame,
                                tracking::TrackingState state, const RecordedFrame& recorded);

  std::unique_ptr<viewer::Viewer> viewer_;
  const loop::LoopCloser& closer_;
  const PinholeCamera& camera_;
  const Undistorter& undistorter_;
  TimingStats& timing_;
  int events_seen_ = 0;   // loops + merges the viewer was told of
  cv::Mat raw_to_ideal_;  // raw -> ideal map at the viewer mask's size (distorting lens)
};

/// Any thread (the viewer's, through System::viewerMap): the active state of map `map_id` (after
/// merges, the map it went into): points with beta, keyframes with their covisibility (the best 4
/// of each) and loop edges, the frames of that map so far; read through the map's thread-safe API
/// (copies).
viewer::ViewerMap viewerMapOf(map::Atlas& atlas, const loop::LoopCloser& closer, const RunRecorder& recorder,
                              std::uint64_t map_id);

}  // namespace ltlo::system
