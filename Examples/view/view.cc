// view: a finished run replayed in the live viewer's picture (issue 30).
//
//   view --run DIR --sequence DIR (--video FILE | --dir DIR)... [--settings FILE] [--online]
//        [--fps F] [--max-frames N] [--progress-every N]
//
// Reads what rgbd_inertial / rgbd wrote to --run (trajectory.txt, or trajectory_online.txt with
// --online; keyframes.txt; static_map.ply; segmentation/ when present) and the sequence's colour
// images, and renders the viewer's two panels (viewer/viewer_renderer.h) at Viewer.Fps pictures per
// second of sequence time (--fps overrides; Viewer.* keys of --settings, the defaults without it)
// to a video (.avi MJPG, .mp4 mp4v) and/or a folder of <frame index>.png, up to the frame of the
// run's last pose. Every due frame is
// rendered (no frame is dropped, unlike the live viewer). The run's files hold no keypoints, no
// covisibility or loop edges and no loop counts, so the replay draws none (run_replay.h). Exit 0,
// 2 on bad input (the file, line and value named).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>

#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "ltlo/core/errors.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/settings_file.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/system/run_outputs.h"
#include "ltlo/viewer/run_replay.h"
#include "ltlo/viewer/viewer.h"
#include "ltlo/viewer/viewer_renderer.h"

namespace {

using namespace ltlo;
namespace fs = std::filesystem;

struct Arguments {
  std::string run_dir;
  std::string sequence_dir;
  std::string video_path;
  std::string png_dir;
  std::string settings_path;
  bool online = false;
  double fps = 0.0;  // 0: Viewer.Fps
  int max_frames = 0;
  int progress_every = 100;
};

viewer::RunRecording readRecording(const Arguments& args) {
  viewer::RunRecording recording;
  const fs::path run(args.run_dir);
  const fs::path trajectory = run / (args.online ? "trajectory_online.txt" : "trajectory.txt");
  if (!fs::exists(trajectory)) throw InputError(trajectory.string(), 0, "no trajectory in the run folder");
  recording.trajectory = io::readTumTrajectory(trajectory.string());
  const fs::path keyframes = run / "keyframes.txt";
  if (fs::exists(keyframes)) {
    for (const system::KeyFrameRecord& keyframe : system::readKeyFrames(keyframes.string())) {
      recording.keyframes.push_back({keyframe.t_s, keyframe.T_w_c, keyframe.map});
    }
  }
  const fs::path map = run / "static_map.ply";
  if (fs::exists(map)) {
    for (const system::MapPointRecord& point : system::readStaticMapPly(map.string())) {
      recording.points.push_back({point.p_w.cast<float>(), static_cast<float>(point.beta)});
    }
  }
  std::fprintf(stderr, "view: %s: %zu poses, %zu keyframes, %zu map points\n", args.run_dir.c_str(),
               recording.trajectory.size(), recording.keyframes.size(), recording.points.size());
  return recording;
}

int run(const Arguments& args) {
  ViewerOptions options;
  if (!args.settings_path.empty()) options = ViewerOptions::load(SettingsFile(args.settings_path));
  if (args.fps > 0.0) options.fps = args.fps;

  io::SequenceReaderOptions reader_options;
  reader_options.read_ground_truth = false;
  const fs::path segmentation = fs::path(args.run_dir) / "segmentation";
  reader_options.read_masks = true;
  reader_options.masks_dir = fs::is_directory(segmentation) ? segmentation.string() : std::string();
  if (!fs::is_directory(segmentation)) std::fprintf(stderr, "view: %s missing: no dynamic tint\n", segmentation.c_str());
  io::SequenceReader reader = io::SequenceReader::open(args.sequence_dir, reader_options);

  viewer::RunRecording recording = readRecording(args);
  // The run saw the frames up to its last pose (a run given --max-frames or stopped part-way saw
  // fewer than the sequence holds): the replay ends there too.
  int run_frames = 0;
  if (!recording.trajectory.empty()) {
    const double last_t = recording.trajectory.back().t_s;
    while (run_frames < reader.frameCount() && reader.frameTime(run_frames) <= last_t + 1e-4) ++run_frames;
  }
  viewer::RunReplay replay(std::move(recording));
  viewer::ViewerRenderer renderer(options);
  const cv::Size size(renderer.width(), renderer.height());
  std::unique_ptr<cv::VideoWriter> video;
  if (!args.video_path.empty()) {
    video = viewer::openViewerVideo(args.video_path, options.fps, size);
  }
  if (!args.png_dir.empty()) {
    std::error_code error;
    fs::create_directories(args.png_dir, error);
    if (error) throw InputError(args.png_dir, 0, "cannot create the folder: " + error.message());
  }

  const int frames = args.max_frames > 0 ? std::min(args.max_frames, run_frames) : run_frames;
  const double interval_s = 1.0 / options.fps;
  double last_picture_t = -1e300;
  int pictures = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < frames; ++i) {
    const double t_s = reader.frameTime(i);
    // The live viewer's pacing (Viewer::due): the first frame, then 1 / fps of sequence time apart.
    const bool due = pictures == 0 || t_s - last_picture_t >= interval_s - 1e-9;
    const io::RgbdImuFrame frame = due ? reader.load(i) : io::RgbdImuFrame{};
    const viewer::ViewerState state = replay.state(i, t_s, frame.color_bgr, frame.mask);
    if (args.progress_every > 0 && i > 0 && i % args.progress_every == 0) {
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::printf("frames %d/%d  pictures %d  %.1f FPS\n", i, frames, pictures, i / std::max(wall, 1e-9));
      std::fflush(stdout);
    }
    if (!due) continue;
    last_picture_t = t_s;
    const viewer::ViewerPicture picture = renderer.render(state);
    if (video) video->write(picture.bgr);
    if (!args.png_dir.empty()) {
      char name[32];
      std::snprintf(name, sizeof(name), "%06d.png", i);
      const std::string path = (fs::path(args.png_dir) / name).string();
      if (!cv::imwrite(path, picture.bgr)) throw InputError(path, 0, "cannot write the picture");
    }
    ++pictures;
  }
  if (video) video->release();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("frames %d\npictures %d\nframes_with_pose %d\nwall_s %.2f\n", frames, pictures, replay.framesWithPose(),
              wall);
  if (!args.video_path.empty()) std::printf("video %s\n", args.video_path.c_str());
  if (!args.png_dir.empty()) std::printf("pictures_dir %s\n", args.png_dir.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"A finished run replayed in the live viewer's picture"};
  Arguments args;
  app.add_option("--run", args.run_dir, "run output folder (trajectory.txt, keyframes.txt, static_map.ply)")
      ->required();
  app.add_option("--sequence", args.sequence_dir, "the sequence the run read (its colour images)")->required();
  app.add_option("--video", args.video_path, "write the pictures to this video (.avi or .mp4)");
  app.add_option("--dir", args.png_dir, "write the pictures as <frame index>.png here");
  app.add_option("--settings", args.settings_path, "settings file with Viewer.* keys (defaults without)");
  app.add_flag("--online", args.online, "the poses tracking returned online (trajectory_online.txt)");
  app.add_option("--fps", args.fps, "pictures per second of sequence time (default Viewer.Fps)")
      ->check(CLI::Range(0.5, 60.0));
  app.add_option("--max-frames", args.max_frames, "stop after this many input frames")->check(CLI::NonNegativeNumber);
  app.add_option("--progress-every", args.progress_every, "a progress line per N frames (0: none)")
      ->check(CLI::NonNegativeNumber);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (args.video_path.empty() && args.png_dir.empty()) {
    std::fprintf(stderr, "view: give --video FILE and/or --dir DIR\n");
    return 2;
  }
  try {
    return run(args);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "view: %s\n", e.what());
    return 2;
  }
}
