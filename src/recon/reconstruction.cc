#include "ltlo/recon/reconstruction.h"

#include <sys/resource.h>

#include <chrono>
#include <filesystem>
#include <optional>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/progress.h"
#include "ltlo/io/associate.h"
#include "ltlo/io/sequence_reader.h"
#include "parallel_frame_loader.h"

namespace ltlo::recon {
namespace {

// Frames decoded ahead of the fusion per loader thread (a VGA frame is about 2.5 MB in memory).
constexpr int kLookaheadPerThread = 3;

io::Trajectory readTrajectory(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(path, 0, "trajectory file does not exist");
  }
  io::Trajectory trajectory = io::readTumTrajectory(path);
  if (trajectory.empty()) throw InputError(path, 0, "trajectory has no poses");
  return trajectory;
}

}  // namespace

double processCpuS() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

ReconstructionResult reconstruct(const ReconstructionRequest& request,
                                 const ReconOptions& options) {
  if (request.every < 1) {
    throw ConfigError("reconstruct: every = " + std::to_string(request.every) +
                      ", expected an integer >= 1");
  }
  options.validate();
  ReconstructionResult result;
  result.trajectory = readTrajectory(request.trajectory_path);

  io::SequenceReaderOptions reader_options;
  reader_options.masks_dir = request.segmentation_dir;  // "" = no masks: never SEQ/masks
  reader_options.calib_override = request.calib_override;
  const io::SequenceReader reader = io::SequenceReader::open(request.sequence_dir, reader_options);
  result.sequence_frames = reader.frameCount();

  // Selected frames with a pose (TUM association, one-to-one).
  std::vector<int> selected;
  for (int i = 0; i < reader.frameCount(); i += request.every) selected.push_back(i);
  result.selected_frames = static_cast<int>(selected.size());
  std::vector<double> frame_times_s, pose_times_s;
  for (int i : selected) frame_times_s.push_back(reader.frameTime(i));
  for (const io::StampedPose& pose : result.trajectory) pose_times_s.push_back(pose.t_s);
  std::vector<int> frames;
  std::vector<SE3> poses;
  for (const auto& [a, b] :
       io::associateTimestamps(frame_times_s, pose_times_s, request.max_pose_dt_s)) {
    const int frame = selected[a];
    if (!request.segmentation_dir.empty() && reader.frameFiles(frame).mask_path.empty()) {
      ++result.frames_without_mask;
      continue;
    }
    frames.push_back(frame);
    poses.push_back(result.trajectory[b].T_w_x);
  }
  result.frames_without_pose =
      result.selected_frames - static_cast<int>(frames.size()) - result.frames_without_mask;
  if (frames.empty()) {
    throw InputError(request.trajectory_path, 0,
                     "no pose within " + std::to_string(request.max_pose_dt_s) +
                         " s of any of the " + std::to_string(result.selected_frames) +
                         " selected frames of " + request.sequence_dir +
                         (result.frames_without_mask > 0 ? " that have a segmentation mask" : ""));
  }
  if (result.frames_without_pose > 0) {
    log::warn(request.trajectory_path, ": ", result.frames_without_pose, " of ",
              result.selected_frames, " selected frames have no pose (not fused)");
  }
  if (result.frames_without_mask > 0) {
    log::warn(request.segmentation_dir, ": ", result.frames_without_mask, " of ",
              result.selected_frames, " selected frames have no mask (not fused)");
  }
  log::info("reconstruct: fusing ", frames.size(), " frames of ", result.sequence_frames,
            request.segmentation_dir.empty()
                ? " (every pixel with depth)"
                : " (static pixels of " + request.segmentation_dir + ")");

  SurfelFusion fusion(reader.calib().camera.camera, options, request.fusion_threads);
  const Undistorter undistorter(reader.calib().camera.model());
  if (undistorter.active()) {
    log::info("reconstruct: lens ", reader.calib().camera.lens.describe(), "; every frame is remapped onto the ideal grid");
  }
  ProgressReporter::Options progress_options;
  progress_options.total_frames = static_cast<long>(frames.size());
  progress_options.log_every_n_frames = request.progress_every > 0 ? request.progress_every : 1;
  if (request.progress_every <= 0) progress_options.style = ProgressReporter::Style::kSilent;
  ProgressReporter progress(progress_options);
  const auto start = std::chrono::steady_clock::now();
  {
    std::vector<uint8_t> with_colour(frames.size());
    for (std::size_t k = 0; k < frames.size(); ++k) with_colour[k] = k % options.colour_every == 0;
    // The loader threads decode and measure frames (SurfelFusion::prepare) while this thread
    // fuses earlier ones.
    ParallelFrameLoader loader(reader, frames, with_colour, request.loader_threads,
                               kLookaheadPerThread * request.loader_threads, &fusion, &undistorter);
    TimingStats loader_timing;
    for (std::size_t k = 0; k < frames.size(); ++k) {
      ScopedTimer wait_timer(loader_timing, "recon.wait_frames");
      std::optional<LoadedFrame> loaded = loader.next();
      wait_timer.stop();
      LTLO_ASSERT(loaded && loaded->frame.index == frames[k], "loader out of order");
      loader_timing.add("recon.measurement", loaded->prepare_s);
      fusion.integrate(toFusionFrame(loaded->frame, poses[k]), loaded->prepared);
      loader.recycle(std::move(loaded->prepared));
      result.fused_frames.push_back(frames[k]);
      progress.frameDone();
    }
    result.timing = fusion.timing().stages();
    result.timing.push_back(loader_timing.stage("recon.measurement"));  // in the loader threads
    result.timing.push_back(loader_timing.stage("recon.wait_frames"));
  }
  progress.finish();
  result.fusion_wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.fps = result.fusion_wall_s > 0.0 ? frames.size() / result.fusion_wall_s : 0.0;
  result.surfels = fusion.stableSurfels();
  result.model_surfels = fusion.numSurfels();
  result.totals = fusion.totals();
  result.model_bytes = fusion.modelBytes();
  return result;
}

}  // namespace ltlo::recon
