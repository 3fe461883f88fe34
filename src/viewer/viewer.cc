#include "ltlo/viewer/viewer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/thread_priority.h"
#include "ltlo/http/mjpeg_server.h"
#include "ltlo/viewer/viewer_renderer.h"

namespace ltlo::viewer {
namespace {

double dynamicShare(const cv::Mat& mask) {
  if (mask.empty()) return 0.0;
  return static_cast<double>(cv::countNonZero(mask)) / static_cast<double>(mask.total());
}

}  // namespace

std::unique_ptr<cv::VideoWriter> openViewerVideo(const std::string& path, double fps, const cv::Size& size) {
  const std::string ext = std::filesystem::path(path).extension().string();
  // OpenCV's own MJPEG writer for .avi (no GStreamer probing, always built in); FFmpeg for .mp4.
  int backend = 0, fourcc = 0;
  if (ext == ".avi") {
    backend = cv::CAP_OPENCV_MJPEG;
    fourcc = cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
  } else if (ext == ".mp4") {
    backend = cv::CAP_FFMPEG;
    fourcc = cv::VideoWriter::fourcc('m', 'p', '4', 'v');
  } else {
    throw InputError(path, 0, "viewer video: unknown extension '" + ext + "' (expected .avi or .mp4)");
  }
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) {
    std::error_code error;
    std::filesystem::create_directories(parent, error);
    if (error) throw InputError(path, 0, "viewer video: cannot create its folder: " + error.message());
  }
  auto video = std::make_unique<cv::VideoWriter>(path, backend, fourcc, fps, size);
  if (!video->isOpened()) throw InputError(path, 0, "viewer video: OpenCV's VideoWriter cannot open it");
  return video;
}

Viewer::Viewer(const ViewerOptions& options, const ViewerOutputs& outputs, MapSource map_source)
    : options_(options), outputs_(outputs), map_source_(std::move(map_source)) {
  const cv::Size size(2 * options.panel_width, options.panel_height);
  if (!outputs.video_path.empty()) {
    video_ = openViewerVideo(outputs.video_path, options.fps, size);
  }
  if (!outputs.png_dir.empty()) {
    std::error_code error;
    std::filesystem::create_directories(outputs.png_dir, error);
    if (error) throw InputError(outputs.png_dir, 0, "viewer: cannot create the folder: " + error.message());
  }
  if (outputs.http_port >= 0) {
    http::ServerOptions server_options;
    server_options.bind_address = outputs.http_bind;
    server_options.port = outputs.http_port;
    server_ = std::make_unique<http::MjpegServer>(server_options);
  }
  log::info("viewer: ", size.width, "x", size.height, " at ", options.fps, " pictures per second of sequence time",
            outputs.video_path.empty() ? "" : ", video " + outputs.video_path,
            outputs.png_dir.empty() ? "" : ", PNGs in " + outputs.png_dir,
            server_ ? ", http port " + std::to_string(server_->port()) : "");
  thread_ = std::thread([this] { run(); });
}

Viewer::~Viewer() { stop(); }

bool Viewer::due(double t_s) const { return t_s >= next_due_t_s_; }

void Viewer::post(ViewerFrame frame) {
  next_due_t_s_ = frame.t_s + 1.0 / options_.fps - 1e-6;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counts_.posted;
    if (pending_) {
      ++counts_.dropped;
      if (!spare_) spare_ = std::move(pending_);
    }
    pending_ = std::move(frame);
    pending_ordinal_ = counts_.posted - 1;
  }
  wake_.notify_one();
}

ViewerFrame Viewer::recycledFrame() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!spare_) return ViewerFrame();
  ViewerFrame frame = std::move(*spare_);
  spare_.reset();
  return frame;
}

void Viewer::postPose(int index, double t_s, const SE3& T_w_c, bool tracked, std::uint64_t map) {
  if (!server_ || !outputs_.pose_stream) return;
  const Vec3& t = T_w_c.translation();
  const Quat& q = T_w_c.quaternion();
  char line[320];
  std::snprintf(line, sizeof(line),
                "{\"frame\": %d, \"t\": %.6f, \"p\": [%.5f, %.5f, %.5f], \"q\": [%.6f, %.6f, %.6f, %.6f], "
                "\"tracked\": %s, \"map\": %llu}",
                index, t_s, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w(), tracked ? "true" : "false",
                static_cast<unsigned long long>(map));
  server_->publishPose(line);
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_.poses;
}

void Viewer::notifyLoop() { loop_flash_.store(true); }

void Viewer::stop() {
  if (stopped_) return;
  stopped_ = true;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
  if (video_) video_->release();
  if (server_) server_->stop();
  const ViewerCounts c = counts();
  log::info("viewer: ", c.rendered, " picture(s) rendered, ", c.dropped, " frame(s) dropped (viewer behind), ",
            c.video_frames, " video frame(s), ", c.png_frames, " PNG(s), ", c.http_frames, " on HTTP");
}

ViewerCounts Viewer::counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counts_;
}

int Viewer::httpPort() const { return server_ ? server_->port() : -1; }

void Viewer::run() {
  log::setThreadName("viewer");
  // Below the SLAM threads (Viewer.ThreadNice): rendering and encoding take the time they leave.
  if (options_.thread_nice > 0) {
    const int nice = lowerCurrentThreadPriority(options_.thread_nice);
    log::debug("viewer: thread nice ", nice);
  }
  std::optional<ViewerRenderer> renderer;
  try {
    renderer.emplace(options_);  // the OSMesa context belongs to this thread
  } catch (const std::exception& e) {
    log::error("viewer: cannot create the renderer: ", e.what(), "; no pictures");
  }
  using Clock = std::chrono::steady_clock;
  std::optional<Clock::time_point> last_wall;
  int last_index = 0;
  double fps = 0.0;
  int flash_pictures_left = 0;
  while (true) {
    std::optional<ViewerFrame> frame;
    std::uint64_t ordinal = 0;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return pending_.has_value() || stopping_; });
      if (!pending_) return;  // stopping with nothing left
      frame = std::move(pending_);
      ordinal = pending_ordinal_;
      pending_.reset();
    }
    if (!renderer) continue;
    ViewerState state;
    state.frame = std::move(*frame);
    const Clock::time_point now = Clock::now();
    if (last_wall) {
      const double dt = std::chrono::duration<double>(now - *last_wall).count();
      const int frames = state.frame.index - last_index;
      if (dt > 0.0 && frames > 0) fps = fps == 0.0 ? frames / dt : 0.7 * fps + 0.3 * (frames / dt);
    }
    last_wall = now;
    last_index = state.frame.index;
    state.fps = fps;
    state.dynamic_share = dynamicShare(state.frame.dynamic_mask);
    // A loop or merge flashes its edges for Viewer.LoopFlashSeconds of sequence time, at least one picture.
    if (loop_flash_.exchange(false)) {
      flash_pictures_left = std::max(1, static_cast<int>(std::lround(options_.loop_flash_s * options_.fps)));
    }
    state.flash_loop_edges = flash_pictures_left > 0;
    if (flash_pictures_left > 0) --flash_pictures_left;
    try {
      state.map = map_source_(state.frame.map);
      write(renderer->render(state).bgr, state.frame.index, ordinal);
    } catch (const std::exception& e) {
      log::error("viewer: ", e.what(), "; picture of frame ", state.frame.index, " lost");
    }
    // Its buffers go back to the tracking thread for the next post (recycledFrame).
    std::lock_guard<std::mutex> lock(mutex_);
    if (!spare_) spare_ = std::move(state.frame);
  }
}

void Viewer::write(const cv::Mat& picture, int frame_index, std::uint64_t post_ordinal) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counts_.rendered;
  }
  if (video_) {
    // One video frame per posted state, so the video plays at the run's pace: a state dropped
    // because the viewer was behind is stood in for by the picture before it (by this one when
    // nothing came before), as a screen recorder repeats a window that did not redraw.
    const std::uint64_t first_missing = video_last_ordinal_ ? *video_last_ordinal_ + 1 : 0;
    const std::uint64_t held = post_ordinal > first_missing ? post_ordinal - first_missing : 0;
    const cv::Mat& stand_in = video_last_.empty() ? picture : video_last_;
    for (std::uint64_t k = 0; k < held; ++k) video_->write(stand_in);
    video_->write(picture);
    picture.copyTo(video_last_);
    video_last_ordinal_ = post_ordinal;
    std::lock_guard<std::mutex> lock(mutex_);
    counts_.video_frames += held + 1;
    counts_.video_held += held;
  }
  if (!outputs_.png_dir.empty()) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", frame_index);
    const std::string path = (std::filesystem::path(outputs_.png_dir) / name).string();
    if (!cv::imwrite(path, picture)) throw InputError(path, 0, "viewer: cannot write the picture");
    std::lock_guard<std::mutex> lock(mutex_);
    ++counts_.png_frames;
  }
  if (server_) {
    std::vector<unsigned char> jpeg;
    cv::imencode(".jpg", picture, jpeg, {cv::IMWRITE_JPEG_QUALITY, options_.jpeg_quality});
    server_->publishJpeg(std::move(jpeg));
    std::lock_guard<std::mutex> lock(mutex_);
    ++counts_.http_frames;
  }
}

}  // namespace ltlo::viewer
