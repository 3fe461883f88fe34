#pragma once
/// The live viewer (issue 30): a thread that renders the run's state (ViewerRenderer) at most
/// Viewer.Fps times per second of sequence time and hands every picture to its outputs: a video
/// file (OpenCV VideoWriter; .avi as MJPG, .mp4 as mp4v), a folder of PNGs, and an HTTP server
/// (http/mjpeg_server.h: /stream.mjpg, /frame.jpg, and each frame's pose on /poses).
///
/// Threads and ownership: System owns the Viewer. The tracking thread calls due() and post()
/// (a copy of its frame) and postPose(); the viewer thread takes the newest posted frame, reads the
/// map for it through MapSource (System::viewerMap: the map's thread-safe API, copies, no lock
/// held afterwards), renders and writes. The tracking thread never waits for the viewer: a frame
/// posted while the previous one is still waiting replaces it (ViewerCounts::dropped). mutex_ is a
/// leaf lock guarding the mailbox and the counts; nothing is called while it is held.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <opencv2/core/types.hpp>

#include "ltlo/core/lie.h"
#include "ltlo/core/settings.h"
#include "ltlo/viewer/viewer_state.h"

namespace cv {
class Mat;
class VideoWriter;
}
namespace ltlo::http {
class MjpegServer;
}

namespace ltlo::viewer {

/// Where the pictures go; the viewer runs when at least one is set.
struct ViewerOutputs {
  std::string video_path;  ///< --viewer-video FILE (.avi or .mp4)
  std::string png_dir;     ///< --viewer-dir DIR: <frame index, 6 digits>.png per picture
  int http_port = -1;      ///< --viewer-http PORT (0: any free port, logged); < 0: no server
  std::string http_bind = "127.0.0.1";  ///< --viewer-bind ADDRESS
  /// --pose-stream: every frame's pose as one JSON line on the server's /poses (needs http_port)
  bool pose_stream = false;

  bool any() const { return !video_path.empty() || !png_dir.empty() || http_port >= 0; }
};

struct ViewerCounts {
  std::uint64_t posted = 0;    ///< frames handed over by tracking
  std::uint64_t rendered = 0;  ///< pictures rendered
  std::uint64_t dropped = 0;   ///< posted frames replaced before the viewer took them
  /// video frames written: every rendered picture, plus the previous picture once more for each
  /// dropped state, so the video keeps sequence time (Viewer.Fps frames per second of the run)
  std::uint64_t video_frames = 0;
  std::uint64_t video_held = 0;  ///< of video_frames, repeats standing in for dropped states
  std::uint64_t png_frames = 0;
  std::uint64_t http_frames = 0;  ///< pictures published to the HTTP server
  std::uint64_t poses = 0;        ///< poses published on /poses
};

/// A viewer video by its extension: .avi MJPG (OpenCV's own writer, always built in), .mp4 mp4v
/// (FFmpeg); its folder is created. Another extension, or a file that cannot be opened, is
/// InputError naming the file.
std::unique_ptr<cv::VideoWriter> openViewerVideo(const std::string& path, double fps, const cv::Size& size);

class Viewer {
 public:
  /// The map state to draw with a frame tracked in map `map_id` (called on the viewer thread).
  using MapSource = std::function<ViewerMap(std::uint64_t map_id)>;

  /// Opens the outputs now (a video that cannot be opened is InputError naming the file, a folder
  /// that cannot be created too; a port that cannot be bound is ConfigError) and starts the thread.
  Viewer(const ViewerOptions& options, const ViewerOutputs& outputs, MapSource map_source);
  /// stop()
  ~Viewer();
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;

  /// Tracking thread: whether a frame at `t_s` should be posted (1 / Viewer.Fps of sequence time
  /// after the last one posted; always the first).
  bool due(double t_s) const;
  /// Tracking thread: hands over a frame (never waits on the viewer).
  void post(ViewerFrame frame);
  /// Tracking thread: a frame to fill for the next post(), holding the buffers of one the viewer
  /// is done with (rendered, or replaced before it was taken): its colour image, mask and keypoint
  /// vector keep their allocation, so a running viewer's post costs a copy and no allocation. Its
  /// other fields are stale; empty before the first frame comes back.
  ViewerFrame recycledFrame();
  /// Tracking thread: one pose on /poses (with ViewerOutputs::pose_stream).
  void postPose(int index, double t_s, const SE3& T_w_c, bool tracked, std::uint64_t map);
  /// Any thread: a loop or merge landed; the next picture flashes the loop edges.
  void notifyLoop();

  /// Renders the frame still waiting, closes the video, stops the server and joins the thread.
  /// Idempotent.
  void stop();

  ViewerCounts counts() const;
  /// The bound HTTP port (-1 without a server).
  int httpPort() const;

 private:
  void run();
  /// Viewer thread: one rendered picture to every output; `post_ordinal` is its state's place
  /// among the posted ones (the video repeats the previous picture for the states dropped before it).
  void write(const cv::Mat& picture, int frame_index, std::uint64_t post_ordinal);

  const ViewerOptions options_;
  const ViewerOutputs outputs_;
  const MapSource map_source_;
  std::unique_ptr<cv::VideoWriter> video_;
  std::unique_ptr<http::MjpegServer> server_;

  double next_due_t_s_ = -1e300;  ///< tracking thread only

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::optional<ViewerFrame> pending_;
  std::uint64_t pending_ordinal_ = 0;  ///< pending_'s place among the posted frames (0-based)
  std::optional<ViewerFrame> spare_;  ///< a frame done with, for recycledFrame()
  bool stopping_ = false;
  ViewerCounts counts_;
  std::atomic<bool> loop_flash_{false};
  std::thread thread_;
  bool stopped_ = false;  ///< caller's thread only (stop())
  // Viewer thread only: the last picture in the video and its post ordinal (none yet: no value).
  cv::Mat video_last_;
  std::optional<std::uint64_t> video_last_ordinal_;
};

}  // namespace ltlo::viewer
