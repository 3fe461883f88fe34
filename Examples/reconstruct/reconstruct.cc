// reconstruct: offline surfel fusion of the static background of a finished run, and headless
// snapshots of it (DESIGN.md "Outputs of a run").
//
//   reconstruct --run DIR --sequence DIR --out DIR [--every N] [--all-pixels]
//               [--trajectory FILE] [--settings YAML] [--size WxH] [--view EX,EY,EZ,TX,TY,TZ]
//               [--fov DEG] [--no-snapshots | --snapshots-only] [--threads N] [--progress-every N]
//
// Poses: RUN/trajectory.txt (TUM, T_w_c); --trajectory FILE replaces it for diagnostics (e.g. the
// sequence's groundtruth.txt; the output then says so). Static pixels: RUN/segmentation_final/ masks
// (the hindsight ones; RUN/segmentation/ when the run has none)
// (255 = dynamic); with --all-pixels, or when the run has no segmentation/, every pixel with depth.
// The sequence's masks/ (ground truth) are never read; its groundtruth.txt only draws the ground-
// truth path in the snapshots. Settings: the Recon.* keys of --settings (defaults without).
// Writes OUT/surfels.ply, OUT/snapshots/*.png, OUT/reconstruct.json and prints "name value" lines;
// --snapshots-only renders the pictures of an existing OUT/surfels.ply again (no fusion).
// Exit status: 0 done, 2 bad input (naming the file), 1 any other error.
#include <CLI/CLI.hpp>
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/process_memory.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/settings_file.h"
#include "ltlo/eval/trajectory_metrics.h"
#include "ltlo/io/metrics_json.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/recon/reconstruction.h"
#include "ltlo/recon/snapshots.h"
#include "ltlo/recon/surfel_ply.h"

namespace {

using namespace ltlo;
namespace fs = std::filesystem;

constexpr int kBadInput = 2;

struct Arguments {
  std::string run_dir;
  std::string sequence_dir;
  std::string out_dir;
  std::string trajectory_path;
  std::string settings_path;
  std::string size = "960x720";
  std::string view;
  double fov_deg = 60.0;
  int every = 1;
  int threads = 2;
  long progress_every = 100;
  bool all_pixels = false;
  bool no_snapshots = false;
  bool snapshots_only = false;
};

recon::SnapshotOptions snapshotOptions(const Arguments& args) {
  recon::SnapshotOptions options;
  char extra = 0;
  if (std::sscanf(args.size.c_str(), "%dx%d%c", &options.width, &options.height, &extra) != 2 ||
      options.width < 64 || options.height < 64 || options.width > 8192 || options.height > 8192) {
    throw ConfigError("--size " + args.size + ", expected <width>x<height> in [64, 8192]");
  }
  options.fov_deg = args.fov_deg;
  if (!args.view.empty()) {
    std::istringstream is(args.view);
    double v[6];
    char comma = 0;
    bool ok = static_cast<bool>(is >> v[0]);
    for (int k = 1; k < 6 && ok; ++k) ok = (is >> comma >> v[k]) && comma == ',';
    if (!ok || !is.eof()) {
      throw ConfigError("--view " + args.view + ", expected EX,EY,EZ,TX,TY,TZ (eye and target, m)");
    }
    options.user_view = recon::UserView{Vec3(v[0], v[1], v[2]), Vec3(v[3], v[4], v[5])};
  }
  return options;
}

// The ground truth mapped into the estimate's world frame (SE3 Umeyama over matched poses), for
// drawing; empty when the sequence has none or too few poses match.
io::Trajectory alignedGroundTruth(const io::SequenceReader& reader, const io::Trajectory& est) {
  if (!reader.hasGroundTruth()) return {};
  const eval::MatchedTrajectories matched = eval::associateTrajectories(reader.groundTruth(), est);
  if (matched.gt.size() < 3) return {};
  const Sim3 S_est_gt = eval::computeAte(matched, /*with_scale=*/false).S_gt_est.inverse();
  io::Trajectory aligned = reader.groundTruth();
  for (io::StampedPose& pose : aligned) pose.T_w_x = S_est_gt.transformPose(pose.T_w_x);
  return aligned;
}

// Four frames (at 1/5 .. 4/5 of the fused ones) with their masks, for the overlay pictures.
std::vector<recon::OverlayFrame> overlayFrames(const io::SequenceReader& reader,
                                               const std::vector<int>& fused_frames) {
  std::vector<recon::OverlayFrame> frames;
  if (fused_frames.empty()) return frames;
  for (int k = 1; k <= 4; ++k) {
    const int index = fused_frames[(fused_frames.size() - 1) * k / 5];
    const io::RgbdImuFrame frame = reader.load(index);
    recon::OverlayFrame overlay;
    overlay.index = index;
    overlay.t_s = frame.t_s;
    overlay.colour_bgr = frame.color_bgr;
    overlay.depth_m = frame.depth_m;
    overlay.dynamic_mask = frame.mask;
    frames.push_back(overlay);
  }
  return frames;
}

int run(const Arguments& args) {
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start_s = recon::processCpuS();
  if (!fs::is_directory(args.run_dir))
    throw InputError(args.run_dir, 0, "run folder does not exist");
  const recon::SnapshotOptions snapshot_options = snapshotOptions(args);
  if (!args.snapshots_only) {  // before the fusion: a bad --out must not cost a whole fusion
    std::error_code error;
    fs::create_directories(args.out_dir, error);
    if (error) throw InputError(args.out_dir, 0, "cannot create the output folder: " + error.message());
  }

  ReconOptions options;
  std::optional<SensorCalib> settings_calib;
  if (!args.settings_path.empty()) {
    const SettingsFile file(args.settings_path);
    options = ReconOptions::load(file);
    if (!fs::is_regular_file(fs::path(args.sequence_dir) / "calib.yaml")) {
      settings_calib = SensorCalib::load(file);
    }
  }

  recon::ReconstructionRequest request;
  request.sequence_dir = args.sequence_dir;
  request.every = args.every;
  request.loader_threads = args.threads;
  request.fusion_threads = args.threads;
  request.progress_every = args.progress_every;
  request.calib_override = settings_calib;
  const bool diagnostic_trajectory = !args.trajectory_path.empty();
  request.trajectory_path = diagnostic_trajectory
                                ? args.trajectory_path
                                : (fs::path(args.run_dir) / "trajectory.txt").string();
  if (diagnostic_trajectory) {
    log::warn("DIAGNOSTIC: fusing with ", args.trajectory_path,
              " instead of the run's own trajectory");
  }
  // The hindsight masks when the run wrote them (a box at rest before it moved is not fused), else the
  // online ones.
  const fs::path final_masks = fs::path(args.run_dir) / "segmentation_final";
  const fs::path segmentation =
      fs::is_directory(final_masks) ? final_masks : fs::path(args.run_dir) / "segmentation";
  std::string pixels = "static (" + segmentation.string() + ")";
  if (args.all_pixels) {
    pixels = "all pixels with depth (--all-pixels)";
  } else if (fs::is_directory(segmentation)) {
    request.segmentation_dir = segmentation.string();
  } else {
    pixels = "all pixels with depth (the run has no segmentation/)";
    log::warn(args.run_dir,
              ": no segmentation/ folder: every pixel with depth is fused; moving "
              "objects enter the model until seen through");
  }

  const std::string ply_path = (fs::path(args.out_dir) / "surfels.ply").string();
  recon::ReconstructionResult result;
  if (args.snapshots_only) {  // pictures of an earlier fusion, e.g. from another viewpoint
    result.surfels = recon::readSurfelPly(ply_path);
    result.trajectory = io::readTumTrajectory(request.trajectory_path);
  } else {
    result = recon::reconstruct(request, options);
    recon::writeSurfelPly(ply_path, result.surfels);
  }

  double snapshot_wall_s = 0.0;
  std::vector<std::string> pictures;
  if (!args.no_snapshots) {
    const auto snapshot_start = std::chrono::steady_clock::now();
    io::SequenceReaderOptions reader_options;
    reader_options.masks_dir = request.segmentation_dir;
    reader_options.calib_override = settings_calib;
    const io::SequenceReader reader = io::SequenceReader::open(args.sequence_dir, reader_options);
    recon::SnapshotScene scene;
    scene.surfels = &result.surfels;
    scene.estimate = result.trajectory;
    scene.estimate_label = diagnostic_trajectory ? "DIAGNOSTIC trajectory " + args.trajectory_path
                                                 : "estimated trajectory";
    scene.ground_truth = alignedGroundTruth(reader, result.trajectory);
    std::vector<int> overlay_candidates = result.fused_frames;
    if (overlay_candidates.empty()) {  // --snapshots-only: any frame
      for (int i = 0; i < reader.frameCount(); ++i) overlay_candidates.push_back(i);
    }
    scene.overlays = overlayFrames(reader, overlay_candidates);
    scene.camera = reader.calib().camera.camera;
    scene.title = fs::path(args.run_dir).filename().string() + " | " + pixels +
                  (diagnostic_trajectory ? " | DIAGNOSTIC poses: " + args.trajectory_path : "");
    pictures = recon::writeSnapshots(scene, snapshot_options,
                                     (fs::path(args.out_dir) / "snapshots").string());
    snapshot_wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - snapshot_start).count();
  }

  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (args.snapshots_only) {
    std::cout << "surfels " << result.surfels.size() << "\nsnapshots_wall_s " << snapshot_wall_s
              << "\n";
    for (const std::string& picture : pictures) std::cout << "snapshot " << picture << "\n";
    return 0;
  }
  io::Metrics metrics;
  metrics.set("surfels", static_cast<int64_t>(result.surfels.size()));
  metrics.set("model_surfels", static_cast<int64_t>(result.model_surfels));
  metrics.set("frames", result.sequence_frames);
  metrics.set("frames_fused", static_cast<int>(result.fused_frames.size()));
  metrics.set("frames_without_pose", result.frames_without_pose);
  metrics.set("frames_without_mask", result.frames_without_mask);
  metrics.set("every", args.every);
  metrics.set("all_pixels", request.segmentation_dir.empty() ? 1 : 0);
  metrics.set("diagnostic_trajectory", diagnostic_trajectory ? 1 : 0);
  metrics.set("surfels_created", static_cast<int64_t>(result.totals.created));
  metrics.set("surfels_merged", static_cast<int64_t>(result.totals.merged));
  metrics.set("removed_unstable", static_cast<int64_t>(result.totals.removed_unstable));
  metrics.set("removed_free_space", static_cast<int64_t>(result.totals.removed_free_space));
  metrics.set("fusion_wall_s", result.fusion_wall_s);
  metrics.set("fusion_fps", result.fps);
  for (const StageTiming& stage : result.timing) {
    std::string key = stage.stage;
    std::replace(key.begin(), key.end(), '.', '_');
    metrics.set(key + "_median_ms", 1e3 * stage.median_s);
    metrics.set(key + "_total_s", stage.total_s);
  }
  metrics.set("snapshots_wall_s", snapshot_wall_s);
  metrics.set("wall_s", wall_s);
  metrics.set("cpu_s", recon::processCpuS() - cpu_start_s);
  metrics.set("peak_memory_mb", peakResidentMb());
  metrics.set("trajectory", request.trajectory_path);
  metrics.set("surfels_ply", ply_path);
  metrics.writeJson((fs::path(args.out_dir) / "reconstruct.json").string());
  std::cout << metrics.toText();
  for (const std::string& picture : pictures) std::cout << "snapshot " << picture << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // Every frame's images (about 3 MB decoded) are allocated by a loader thread and freed after
  // fusion. With glibc's defaults such blocks are mmapped or trimmed back to the kernel and the
  // next frame faults its pages in again (200 000 page faults, ~7 % of the CPU time on a 45 s VGA
  // sequence). Keep them on the heap for reuse: the few frames in flight cost tens of MB at most.
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
  log::initFromEnvironment();
  CLI::App app{"Offline surfel reconstruction of the static background of a run, and snapshots"};
  Arguments args;
  app.add_option("--run", args.run_dir, "run folder (trajectory.txt, segmentation/)")->required();
  app.add_option("--sequence", args.sequence_dir, "the run's sequence (rgb, depth, calib.yaml)")
      ->required();
  app.add_option("--out", args.out_dir, "output folder (surfels.ply, snapshots/)")->required();
  app.add_option("--every", args.every, "fuse every n-th frame")->check(CLI::PositiveNumber);
  app.add_flag("--all-pixels", args.all_pixels,
               "fuse every pixel with depth, ignoring the run's segmentation");
  app.add_option("--trajectory", args.trajectory_path,
                 "DIAGNOSTIC: poses from this TUM file instead of RUN/trajectory.txt");
  app.add_option("--settings", args.settings_path, "settings YAML (its Recon.* keys)");
  app.add_option("--size", args.size, "snapshot size WxH");
  app.add_option("--view", args.view,
                 "extra snapshot from eye EX,EY,EZ towards TX,TY,TZ (m, world)");
  app.add_option("--fov", args.fov_deg, "horizontal field of view of the snapshot cameras (deg)")
      ->check(CLI::Range(10.0, 150.0));
  app.add_flag("--no-snapshots", args.no_snapshots, "write surfels.ply only");
  app.add_flag("--snapshots-only", args.snapshots_only,
               "no fusion: render the snapshots of OUT/surfels.ply written earlier (e.g. with "
               "another --view or --size)");
  app.add_option("--threads", args.threads, "frame decoding threads, and fusion threads")
      ->check(CLI::Range(1, 16));
  app.add_option("--progress-every", args.progress_every,
                 "progress line every N frames when not on a terminal (0 = none)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "reconstruct: " << e.what() << "\n" << app.help();
    return kBadInput;
  }
  try {
    return run(args);
  } catch (const InputError& e) {
    std::cerr << "reconstruct: " << e.what() << "\n";
    return kBadInput;
  } catch (const ConfigError& e) {
    std::cerr << "reconstruct: " << e.what() << "\n";
    return kBadInput;
  } catch (const std::exception& e) {
    std::cerr << "reconstruct: error: " << e.what() << "\n";
    return 1;
  }
}
