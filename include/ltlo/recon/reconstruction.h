#pragma once
/// Offline reconstruction of a finished run: fuses the static pixels of a sequence's frames, posed
/// by the run's trajectory, into surfels (SurfelFusion). Frames are decoded and measured ahead in
/// loader threads (PNG decoding costs about as much as fusing; the measurement does not depend on
/// the model); the model's stages of each frame are split over `fusion_threads` (the calling
/// thread and workers of its own). Threads: the request's reader
/// and buffers are private to the call; nothing is shared with a running SLAM system.
///
///   ReconstructionRequest request;
///   request.sequence_dir = "seq";
///   request.trajectory_path = "run/trajectory.txt";
///   request.segmentation_dir = "run/segmentation";
///   ReconstructionResult result = reconstruct(request, settings.recon);   // progress with FPS
///
/// Which pixels are static comes from `segmentation_dir` (<timestamp>.png, 255 = dynamic, the
/// input's size); frames without a mask there are skipped. Without it every pixel with depth is
/// fused (moving objects then enter the model until free-space violations remove them).
/// The sequence's own masks/ (ground truth) are never read.
#include <optional>
#include <string>
#include <vector>

#include "ltlo/core/calib.h"
#include "ltlo/core/settings.h"
#include "ltlo/io/trajectory_io.h"
#include "ltlo/recon/surfel.h"
#include "ltlo/recon/surfel_fusion.h"

namespace ltlo::recon {

struct ReconstructionRequest {
  std::string sequence_dir;      ///< DATA_FORMAT.md sequence (rgb, depth, calib.yaml)
  std::string trajectory_path;   ///< TUM trajectory, T_w_c
  std::string segmentation_dir;  ///< run's segmentation/; empty = every pixel with depth
  int every = 1;                 ///< fuse every n-th frame (>= 1)
  int loader_threads = 2;        ///< decoding threads
  int fusion_threads = 2;        ///< threads splitting each frame's fusion (the caller's included)
  double max_pose_dt_s = 0.005;  ///< frame to trajectory timestamp tolerance
  /// Calibration for sequences without calib.yaml (TUM RGB-D, OpenLORIS), from a settings file.
  std::optional<SensorCalib> calib_override;
  /// Progress line every this many frames when stderr is not a terminal (0 = silent).
  long progress_every = 100;
};

struct ReconstructionResult {
  std::vector<Surfel> surfels;    ///< stable surfels
  std::size_t model_surfels = 0;  ///< all surfels at the end, stable or not
  io::Trajectory trajectory;      ///< the trajectory file as read
  std::vector<int> fused_frames;  ///< sequence frame indices fused, in order
  int sequence_frames = 0;
  int selected_frames = 0;      ///< every n-th frame
  int frames_without_pose = 0;  ///< selected frames with no trajectory pose within tolerance
  int frames_without_mask = 0;  ///< selected frames with no segmentation mask (skipped)
  FusionTotals totals;
  double fusion_wall_s = 0.0;   ///< wall time of the fusion loop
  double fps = 0.0;             ///< fused frames per second of wall time
  std::size_t model_bytes = 0;  ///< surfel storage at the end
  /// Fusion stages (SurfelFusion::timing()), recon.measurement (per frame, in a loader thread)
  /// and recon.wait_frames, the fusion thread waiting for decoded and measured frames.
  std::vector<StageTiming> timing;
};

/// Runs the fusion. Throws InputError naming the file for a missing or malformed trajectory, a
/// trajectory with no pose for any frame, an unreadable sequence or a bad mask; ConfigError for
/// options out of range.
ReconstructionResult reconstruct(const ReconstructionRequest& request, const ReconOptions& options);

/// CPU time (user + system) of this process so far, s. (Its peak memory: ltlo::peakResidentMb.)
double processCpuS();

}  // namespace ltlo::recon
