// rgbd_inertial / rgbd: SLAM on one RGB-D(-inertial) sequence; writes the run outputs.
//
//   rgbd_inertial --settings YAML --sequence DIR --out DIR [--vocabulary FILE] [--no-imu]
//                 [--single-thread] [--first-frame N] [--max-frames N] [--progress-every N] [--oracle-masks]
//                 [--rate R]
//                 [--set Key=Value]... [--viewer-video FILE] [--viewer-dir DIR]
//                 [--viewer-http PORT [--viewer-bind ADDRESS] [--pose-stream]]
//                 [--save-atlas FILE] [--load-atlas FILE [--localisation-only | --resume]]
//   rgbd_inertial --settings YAML --bag FILE [--bag-preset tum|realsense|realsense-unite|openloris]
//                 [--rgb-topic T] [--depth-topic T] [--imu-topic T | --accel-topic T --gyro-topic T]
//                 [--camera-info-topic T] [--calib FILE] [--groundtruth FILE] --out DIR [options as above]
//   rgbd_inertial --bag FILE --list-topics      (topics, types, counts and rates; nothing else)
//   rgbd          (the same program without the IMU: TUM RGB-D with config_yaml/tum_rgbd.yaml)
//
// A ROS 1 bag (--bag) is read directly (io::SequenceReader::openBag): the preset names the topics,
// each --*-topic replaces one. Its calibration: --calib FILE (a calib.yaml of DATA_FORMAT.md) when
// given, else the bag's CameraInfo for the camera (size, K, distortion; a difference from the
// settings' Camera.* is one warning) with the IMU keys of the settings file. A bag has no ground
// truth: the run writes metrics.json only with --groundtruth FILE (TUM text, read after the run).
//
// The calibration comes from DIR/calib.yaml when the sequence has one (DATA_FORMAT.md), otherwise
// from the Camera.* / IMU.* keys of the settings file (TUM RGB-D, OpenLORIS). Outputs in --out:
// trajectory.txt, trajectory_online.txt (each frame's pose as tracking returned it, never corrected
// afterwards), keyframes.txt, static_map.ply, and metrics.json when DIR/groundtruth.txt exists.
// The evaluation inputs DIR/groundtruth.txt and DIR/masks/ are read only after the run, once its
// outputs are written: a malformed one leaves the run and its outputs as they are, and metrics.json
// lacks the figures it would give but has "evaluation_error" (file, line, value). --oracle-masks
// (diagnostic ablation): DIR/masks/ replaces the segmentation (metrics.json "oracle_masks": true);
// without it masks/ is not opened before the evaluation.
// --rate R plays the sequence at R times its recorded speed, as a live camera delivers it (frames
// wait for their stamps; one that starts late is still tracked, never dropped), so local mapping and
// loop closing get the time a robot gives them; the summary says how many frames started more than a
// frame interval late. Without it (or 0) frames follow each other as fast as tracking goes.
// --set Key=Value (repeatable) replaces one key of the settings file (or of calib.yaml for Camera.*,
// IMU.*, DepthMapFactor), validated like the file and logged; an unknown key is bad input.
// Ctrl-C (or SIGTERM), a bad frame or an error part-way stop the run, shut the threads down and
// still write the outputs of the frames processed (Ctrl-C is handled from the start, also while
// loading). Exit status: 0 done (also when interrupted), 2 bad input (files, settings, the
// vocabulary; for rgbd_inertial a sequence without IMU samples or IMU calibration), 1 any other
// error, 3 the run completed and its outputs are written but the evaluation failed (a malformed
// groundtruth.txt or masks/; a 2 or 1 of the run itself takes precedence).
// --save-atlas FILE writes the maps at the end (also after Ctrl-C or an error part-way: what was
// mapped until then); --load-atlas FILE starts the run lost in a saved atlas, relocalises in it and
// tracks in its world frame (trajectory.txt then needs no alignment to the earlier run's), extending
// it; --localisation-only adds nothing to it (Tracking.LocalisationOnly); --resume continues the run
// that saved it instead (its run state: tracking, mapping, loop closing and the records go on at its
// next frame; --first-frame defaults to that frame). A bad atlas file (truncated, corrupt, another
// vocabulary or camera, no run state to resume) is bad input: exit 2 naming the file, section and byte.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "bag_topic_options.h"
#include "bow/vocabulary.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/frame_pacer.h"
#include "ltlo/core/log.h"
#include "ltlo/core/progress.h"
#include "ltlo/core/settings.h"
#include "ltlo/core/thread_names.h"
#include "ltlo/io/frame_prefetcher.h"
#include "ltlo/io/sequence_reader.h"
#include "ltlo/system/hindsight_masks.h"
#include "ltlo/system/run_outputs.h"
#include "ltlo/system/system.h"

#ifndef LTLO_PROGRAM_NAME
#define LTLO_PROGRAM_NAME "rgbd_inertial"
#endif
#ifndef LTLO_PROGRAM_USES_IMU
#define LTLO_PROGRAM_USES_IMU 1
#endif

namespace {

using namespace ltlo;
namespace fs = std::filesystem;

constexpr const char* kProgram = LTLO_PROGRAM_NAME;
constexpr const char* kShippedVocabulary = "Vocabulary/ltlo_orb_k10_L5.bin";
/// The run completed and its outputs are written, but groundtruth.txt or masks/ could not be read.
constexpr int kExitEvaluationFailed = 3;

std::atomic<bool> g_stop_requested{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void onStopSignal(int signal_number) {
  g_stop_requested.store(true);
  std::signal(signal_number, SIG_DFL);  // a second Ctrl-C ends the program at once
}

struct Arguments {
  std::string settings_path;
  std::string sequence_dir;
  std::string bag_path;     ///< --bag: a ROS 1 bag instead of a sequence folder
  io::BagTopics bag_topics;  ///< the preset with each --*-topic given replacing one
  std::string calib_path;   ///< --calib: calib.yaml for a bag
  std::string groundtruth_path;  ///< --groundtruth: a bag run's evaluation ground truth (TUM text)
  bool list_topics = false;
  std::string out_dir;
  std::string vocabulary_path;
  bool no_imu = !LTLO_PROGRAM_USES_IMU;
  bool single_thread = false;
  bool oracle_masks = false;
  /// --carried-variants: also trajectory_carried_{none,blend,bridge}.txt (the A/B of one run)
  bool carried_variants = false;
  long max_frames = 0;
  long first_frame = 0;  ///< --first-frame N: start at frame N (e.g. the second half of a sequence)
  long progress_every = 100;
  double rate = 0.0;  ///< --rate R: play at R times the recorded speed (0: as fast as tracking goes)
  std::vector<std::string> overrides;  ///< --set Key=Value, in order
  std::string viewer_video;            ///< --viewer-video FILE
  std::string viewer_dir;              ///< --viewer-dir DIR
  int viewer_http = -1;                ///< --viewer-http PORT
  std::string viewer_bind = "127.0.0.1";
  bool pose_stream = false;
  std::string save_atlas;  ///< --save-atlas FILE
  std::string load_atlas;  ///< --load-atlas FILE
  bool localisation_only = false;
  bool resume = false;             ///< --resume: continue the run the loaded atlas saved
  bool first_frame_given = false;  ///< --first-frame was on the command line
};

/// Sleeps until a paced frame is due, in steps of at most 50 ms so that Ctrl-C is not held up by a
/// slow rate.
void waitUntilDue(double seconds) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point until =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  while (!g_stop_requested.load()) {
    const Clock::time_point now = Clock::now();
    if (now >= until) return;
    std::this_thread::sleep_for(std::min<Clock::duration>(until - now, std::chrono::milliseconds(50)));
  }
}

/// The shipped vocabulary: $LTLO_SOURCE_DIR, then next to the executable's build tree
/// (<root>/build/bin/<program> -> <root>), then the source tree this program was built from, then
/// the working directory.
std::string defaultVocabularyPath() {
  std::vector<fs::path> roots;
  if (const char* env = std::getenv("LTLO_SOURCE_DIR")) roots.emplace_back(env);
  std::error_code error;
  const fs::path exe = fs::read_symlink("/proc/self/exe", error);
  if (!error) {
    roots.push_back(exe.parent_path().parent_path().parent_path());
    roots.push_back(exe.parent_path().parent_path());
  }
#ifdef LTLO_SOURCE_DIR_AT_BUILD
  roots.emplace_back(LTLO_SOURCE_DIR_AT_BUILD);
#endif
  roots.push_back(fs::current_path(error));
  for (const fs::path& root : roots) {
    const fs::path candidate = root / kShippedVocabulary;
    if (fs::is_regular_file(candidate, error)) return candidate.string();
  }
  throw InputError(kShippedVocabulary, 0, "shipped vocabulary not found (give --vocabulary FILE)");
}

/// Settings and reader options: the calibration from DIR/calib.yaml when present, else from the
/// settings file (then also handed to the reader, which has no calib.yaml to read).
/// How far each frame's IMU samples reach beyond its interval (s): the online time-offset estimate
/// is clamped to +-50 ms (TimeOffsetOptions::max_abs_shift_s), with a frame's ramp step to spare.
constexpr double kImuMarginS = 0.06;

struct RunSetup {
  Settings settings;
  io::SequenceReaderOptions reader_options;
};
RunSetup loadSetup(const Arguments& args) {
  RunSetup setup;
  const bool bag = !args.bag_path.empty();
  const fs::path calib_path = bag ? fs::path(args.calib_path) : fs::path(args.sequence_dir) / "calib.yaml";
  if (bag && !args.calib_path.empty() && !fs::is_regular_file(calib_path)) {
    throw InputError(args.calib_path, 0, "calibration file (--calib) does not exist");
  }
  const bool has_calib_file = !calib_path.empty() && fs::is_regular_file(calib_path);
  std::vector<SettingOverride> overrides;
  for (const std::string& text : args.overrides) overrides.push_back(SettingOverride::parse(text));
  setup.settings = Settings::load(args.settings_path, has_calib_file ? calib_path.string() : "", overrides);
  setup.reader_options.sequence = setup.settings.sequence;
  // The reader takes the calibration the settings resolved (--set on a calibration key reaches it).
  setup.reader_options.calib_override = setup.settings.calib;
  // Room for the online camera-IMU offset estimate to cut each frame's IMU interval elsewhere.
  if (setup.settings.local_mapping.estimate_time_offset) setup.reader_options.imu_margin_s = kImuMarginS;
  setup.reader_options.calib_override_source = setup.settings.calib_path;
  // A bag without --calib: its CameraInfo is the camera's calibration (the settings keep the IMU).
  setup.reader_options.prefer_camera_info = bag && !has_calib_file;
  if (bag) {
    if (!has_calib_file) {
      log::info(kProgram, ": no --calib; the camera from the bag's CameraInfo when it has one, the IMU keys from ",
                args.settings_path);
    }
  } else if (!has_calib_file) {
    log::info(kProgram, ": ", calib_path.string(), " not found; calibration (Camera.*, DepthMapFactor",
              setup.settings.calib.has_imu ? ", IMU.*" : "", ") from the settings file ", args.settings_path);
  }
  if (args.localisation_only) setup.settings.tracking.localisation_only = true;
  setup.reader_options.read_masks = args.oracle_masks;
  setup.reader_options.read_ground_truth = false;  // evaluation only: read after the run
  return setup;
}

/// RGB-D-inertial needs IMU samples and an IMU calibration; without them the run is an input
/// error, not a silent RGB-D run.
void requireImu(const io::SequenceReader& reader, const Settings& settings) {
  const std::string advice = "; run rgbd or pass --no-imu for RGB-D only";
  if (!reader.hasImu()) {
    if (reader.isBag() && reader.imuPath().empty()) {
      throw InputError(reader.directory(), 0,
                       "no IMU topic given (--imu-topic, or --accel-topic and --gyro-topic, or a --bag-preset with "
                       "them)" + advice);
    }
    const std::string imu_path =
        reader.imuPath().empty() ? (fs::path(reader.directory()) / "imu.txt").string() : reader.imuPath();
    throw InputError(imu_path, 0,
                     std::string(reader.imuPath().empty() ? "missing" : "has no IMU samples") +
                         " (no IMU data in the sequence)" + advice);
  }
  if (!settings.calib.has_imu) {
    throw ConfigError(settings.calib_path + ": no IMU calibration (IMU.T_b_c1 and the noise keys)" + advice);
  }
}

std::string frameName(const io::SequenceReader& reader, int index) {
  if (index < 0 || index >= reader.frameCount()) return "frame " + std::to_string(index);
  const io::FrameFiles& files = reader.frameFiles(index);
  return "frame " + std::to_string(index) + " (t = " + std::to_string(files.t_s) + " s, " + files.color_path + ")";
}

/// --resume: the frame the saved run goes on at (--first-frame, when given, must name it), checked
/// against the sequence (the saved run's last frame must be the one before); the segmenter's
/// previous frame rebuilt from that frame's images.
long resumeAt(const Arguments& args, io::SequenceReader& reader, const system::ResumePoint& resume,
              system::System& slam) {
  const long next = static_cast<long>(resume.next_frame_index);
  if (args.first_frame_given && args.first_frame != next) {
    throw InputError(args.load_atlas, 0,
                     "its run goes on at frame " + std::to_string(next) + ", not at --first-frame " +
                         std::to_string(args.first_frame));
  }
  if (next > reader.frameCount()) {
    throw InputError(reader.directory(), 0,
                     "has " + std::to_string(reader.frameCount()) + " frames; the run saved in " + args.load_atlas +
                         " goes on at frame " + std::to_string(next));
  }
  if (next > 0 && reader.frameTime(static_cast<int>(next) - 1) != resume.last_frame_t_s) {
    throw InputError(reader.directory(), 0,
                     "frame " + std::to_string(next - 1) + " is at t = " +
                         std::to_string(reader.frameTime(static_cast<int>(next) - 1)) + " s, the last frame of the run "
                         "saved in " + args.load_atlas + " at t = " + std::to_string(resume.last_frame_t_s) +
                         " s: another sequence");
  }
  // The segmenter's kept frames (Dense.ReferenceBaseline), oldest first, found by their times.
  int search_from = static_cast<int>(next) - 2;
  for (const double t_s : resume.kept_frame_t_s) {
    int index = search_from;
    while (index >= 0 && reader.frameTime(index) > t_s) --index;
    if (index < 0 || reader.frameTime(index) != t_s) {
      throw InputError(reader.directory(), 0,
                       "has no frame at t = " + std::to_string(t_s) + " s, a frame the run saved in " + args.load_atlas +
                           " keeps: another sequence");
    }
    slam.restoreKeptFrame(reader.load(index));
  }
  if (resume.previous_frame_t_s) slam.restorePreviousFrame(reader.load(static_cast<int>(next) - 1));
  log::info(kProgram, ": resuming the run of ", args.load_atlas, " at frame ", next);
  return next;
}

/// segmentation_final/ (Seg.HindsightMasks): the online masks relabelled against the final map. A failure
/// is logged and leaves no folder; it never costs the run's other outputs.
void writeFinalMasks(const Arguments& args, const RunSetup& setup, const system::RunReport& report) {
  const fs::path online = fs::path(args.out_dir) / "segmentation";
  const fs::path final_dir = fs::path(args.out_dir) / "segmentation_final";
  std::error_code error;
  fs::remove_all(final_dir, error);  // never a stale folder from an earlier run into this one
  if (!setup.settings.segmentation.hindsight_masks || !setup.settings.segmentation.enable || args.oracle_masks ||
      !args.bag_path.empty() || !fs::is_directory(online, error) || fs::is_empty(online, error)) {
    return;
  }
  try {
    io::SequenceReaderOptions reader_options = setup.reader_options;
    reader_options.masks_dir = online.string();
    reader_options.read_ground_truth = false;
    const io::SequenceReader reader = io::SequenceReader::open(args.sequence_dir, reader_options);
    const system::HindsightMaskResult result = system::writeHindsightMasks(
        reader, report.trajectory, report.keyframes, report.map_points_map, report.map_points, setup.settings.calib.camera.model(),
        system::HindsightMaskOptions::from(setup.settings), final_dir.string(), report.trajectory_online);
    log::info(kProgram, ": hindsight masks: ", result.frames_written, " written to ", final_dir.string(), ", ",
              result.frames_relabelled, " relabelled against the final map, ", result.frames_changed, " changed (",
              result.regions_flipped, " regions static -> dynamic (", result.regions_free_space, " by free space), ",
              result.regions_to_static, " dynamic -> static, ", result.voting_points, " static points, ",
              result.free_space_views, " keyframe and ", result.free_space_frame_views, " frame depths, ",
              result.frames_relabelled > 0 ? static_cast<double>(result.views_asked) / result.frames_relabelled : 0.0,
              " asked a frame; depth noise ", result.measured_noise_m * 1000.0, " mm at 1 m measured), ", result.frames_rejudged, " judged again at the final poses (",
              result.rejudge_seconds, " s), in ", result.seconds, " s");
  } catch (const std::exception& e) {
    log::error(kProgram, ": hindsight masks not written: ", e.what());
    fs::remove_all(final_dir, error);
  }
}

int run(const Arguments& args) {
  const auto start = std::chrono::steady_clock::now();
  RunSetup setup = loadSetup(args);
  io::SequenceReader reader = args.bag_path.empty()
                                  ? io::SequenceReader::open(args.sequence_dir, setup.reader_options)
                                  : io::SequenceReader::openBag(args.bag_path, args.bag_topics, setup.reader_options);
  if (reader.isBag()) {
    // The camera may come from CameraInfo: the system runs on what the reader resolved.
    setup.settings.calib = reader.calib();
  }
  setup.settings.log();
  const std::string vocabulary_path = args.vocabulary_path.empty() ? defaultVocabularyPath() : args.vocabulary_path;
  log::info(kProgram, ": vocabulary ", vocabulary_path);
  auto vocabulary = std::make_shared<const bow::Vocabulary>(bow::Vocabulary::load(vocabulary_path));

  system::SystemOptions options;
  options.use_imu = !args.no_imu;
  options.threaded = !args.single_thread;
  options.oracle_masks = args.oracle_masks;
  if (args.oracle_masks) log::warn(kProgram, ": --oracle-masks: ground-truth masks replace the segmentation (a diagnostic run)");
  options.segmentation_dir = (fs::path(args.out_dir) / "segmentation").string();
  options.viewer_video_path = args.viewer_video;
  options.viewer_png_dir = args.viewer_dir;
  options.viewer_http_port = args.viewer_http;
  options.viewer_http_bind = args.viewer_bind;
  options.viewer_pose_stream = args.pose_stream;
  options.load_atlas_path = args.load_atlas;
  options.resume = args.resume;
  if (options.use_imu) requireImu(reader, setup.settings);
  system::System slam(setup.settings, vocabulary, options);

  log::setThreadName("tracking");

  long first_frame = args.first_frame;
  if (const std::optional<system::ResumePoint> resume = slam.resumePoint()) first_frame = resumeAt(args, reader, *resume, slam);
  reader.seek(static_cast<int>(std::min<long>(first_frame, reader.frameCount() + 1L)));
  const long remaining = reader.frameCount() - first_frame;
  const long total = args.max_frames > 0 ? std::min<long>(args.max_frames, remaining) : remaining;
  ProgressReporter progress({"frames", total, ProgressReporter::Style::kSilent});
  int exit_code = 0;
  std::string failure;
  int frames = 0;
  // Images are decoded a few frames ahead in a reader thread while the previous frame is tracked.
  io::FramePrefetcher prefetcher(reader, 4, total);
  FramePacer pacer(args.rate);
  try {
    while (!g_stop_requested.load() && frames < total) {
      std::optional<io::RgbdImuFrame> input = prefetcher.next();
      if (!input) break;
      if (pacer.enabled()) {
        waitUntilDue(pacer.secondsUntilDue(input->t_s));
        if (g_stop_requested.load()) break;
        const double lag_s = pacer.frameStarts();
        if (pacer.lastFrameLate()) {
          log::debug("frame ", input->index, " (t ", input->t_s, " s) started ", 1e3 * lag_s, " ms late");
        }
      }
      const tracking::TrackingState state = slam.trackFrame(*input);
      ++frames;
      progress.frameDone();
      if (args.progress_every > 0 && frames % args.progress_every == 0) {
        const system::SystemCounts counts = slam.counts();
        log::info(ProgressReporter::formatStatus("frames", progress.status()), " | ",
                  tracking::trackingStateName(state), " | keyframes ", counts.keyframes, " | maps ", counts.maps,
                  " | loops ", counts.loops, " | merges ", counts.merges);
      }
    }
  } catch (const InputError& e) {
    failure = "bad input at " + frameName(reader, static_cast<int>(first_frame) + frames) + ": " + e.what();
    exit_code = 2;
  } catch (const ConfigError& e) {
    failure = "bad settings at " + frameName(reader, static_cast<int>(first_frame) + frames) + ": " + e.what();
    exit_code = 2;
  } catch (const std::exception& e) {
    failure = "error at " + frameName(reader, static_cast<int>(first_frame) + frames) + ": " + e.what();
    exit_code = 1;
  }
  prefetcher.stop();  // the reader is the prefetch thread's until joined
  if (!failure.empty()) log::error(kProgram, ": ", failure);
  const bool interrupted = g_stop_requested.load() || !failure.empty();
  progress.finish();
  if (pacer.enabled()) log::info(kProgram, ": ", pacer.summary());

  slam.shutdown(!interrupted);
  if (!args.save_atlas.empty()) {
    try {
      slam.saveAtlas(args.save_atlas);
    } catch (const std::exception& e) {
      log::error(kProgram, ": atlas not saved: ", e.what());
      if (exit_code == 0) exit_code = dynamic_cast<const InputError*>(&e) != nullptr ? 2 : 1;
    }
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  system::RunReport report = slam.report(wall_s);
  report.interrupted = interrupted;
  if (pacer.enabled()) {
    const FramePacerStats paced = pacer.stats();
    report.pacing_rate = pacer.rate();
    report.paced_late_frames = paced.late_frames;
    report.paced_lag_mean_ms = 1e3 * paced.mean_lag_s;
    report.paced_lag_max_ms = 1e3 * paced.max_lag_s;
  }
  writeFinalMasks(args, setup, report);
  const fs::path masks_dir = fs::path(args.sequence_dir) / "masks";
  system::EvaluationInputs evaluation;
  evaluation.ground_truth_path = reader.isBag() ? args.groundtruth_path : reader.groundTruthPath();
  evaluation.gt_masks_dir = !reader.isBag() && fs::is_directory(masks_dir) ? masks_dir.string() : "";
  const system::WrittenOutputs written =
      system::writeRunOutputs(args.out_dir, report, evaluation, setup.settings.local_mapping.min_point_beta);

  if (args.carried_variants) {
    const std::pair<const char*, system::CarriedCorrection> variants[] = {
        {"none", system::CarriedCorrection::kNone},
        {"blend", system::CarriedCorrection::kBlend},
        {"bridge", system::CarriedCorrection::kBridge}};
    for (const auto& [name, correction] : variants) {
      system::writeTrajectory((fs::path(args.out_dir) / (std::string("trajectory_carried_") + name + ".txt")).string(),
                              slam.trajectory(correction));
    }
  }
  const system::SystemCounts& counts = report.counts;
  std::printf("frames %d\nframes_with_pose %d\nframes_tracked %d\nkeyframes %d\nmap_points %d\nstatic_points %d\n"
              "maps %d\nmaps_created %d\nloops %d\nmerges %d\nwall_s %.3f\nfps %.2f\npeak_memory_mb %.1f\n",
              counts.frames, counts.frames_with_pose, counts.frames_tracked, counts.keyframes, counts.map_points,
              written.static_points, counts.maps, counts.maps_created, counts.loops, counts.merges, wall_s,
              wall_s > 0.0 ? counts.frames / wall_s : 0.0, report.peak_memory_mb);
  if (written.has_metrics && written.metrics.has("ate_rmse_m")) {
    std::printf("ate_rmse_m %.6f\nrpe_trans_rmse_m_s %.6f\nrpe_rot_rmse_deg_s %.6f\n",
                written.metrics.number("ate_rmse_m"), written.metrics.number("rpe_trans_rmse_m_s"),
                written.metrics.number("rpe_rot_rmse_deg_s"));
  }
  if (written.has_metrics && written.metrics.has("ate_online_rmse_m")) {
    std::printf("ate_online_rmse_m %.6f\n", written.metrics.number("ate_online_rmse_m"));
  }
  if (written.has_metrics && written.metrics.has("static_iou")) {
    std::printf("static_iou %.4f\nstatic_iou_occluded %.4f\ndynamic_recall %.4f\nstatic_share %.4f\n",
                written.metrics.number("static_iou"), written.metrics.number("static_iou_occluded"),
                written.metrics.number("dynamic_recall"), written.metrics.number("static_share"));
  }
  if (written.has_metrics && written.metrics.has("static_iou_final")) {
    std::printf("static_iou_final %.4f\ndynamic_recall_final %.4f\n", written.metrics.number("static_iou_final"),
                written.metrics.number("dynamic_recall_final"));
  }
  if (counts.frames > counts.frames_with_pose) {
    log::warn(kProgram, ": ", counts.frames - counts.frames_with_pose,
              " frame(s) before the first initialisation have no pose");
  }
  std::printf("outputs %s\n", args.out_dir.c_str());
  const std::vector<std::string> threads_left = runningNamedThreads();
  if (threads_left.empty()) {
    log::info(kProgram, ": all threads joined");
  } else {
    std::string names;
    for (const std::string& name : threads_left) names += " " + name;
    log::error(kProgram, ": ", threads_left.size(), " thread(s) still running after shutdown:", names);
  }
  if (!failure.empty()) {
    std::fprintf(stderr, "%s: stopped after %d frames (%s); outputs written to %s\n", kProgram, frames,
                 failure.c_str(), args.out_dir.c_str());
  } else if (g_stop_requested.load()) {
    std::fprintf(stderr, "%s: interrupted after %d frames; outputs written to %s\n", kProgram, frames,
                 args.out_dir.c_str());
  }
  if (!written.evaluation_error.empty()) {
    std::fprintf(stderr, "%s: evaluation failed: %s; the run's outputs are written to %s (metrics.json "
                 "without those figures, with evaluation_error)\n",
                 kProgram, written.evaluation_error.c_str(), args.out_dir.c_str());
    if (exit_code == 0) exit_code = kExitEvaluationFailed;
  }
  std::fflush(stdout);
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  // First thing: Ctrl-C at any moment (also while loading) ends with the outputs written.
  std::signal(SIGINT, onStopSignal);
  std::signal(SIGTERM, onStopSignal);
  CLI::App app{LTLO_PROGRAM_USES_IMU ? "RGB-D-inertial SLAM on a sequence; writes the run outputs"
                                     : "RGB-D SLAM (no IMU) on a sequence; writes the run outputs"};
  Arguments args;
  examples::BagTopicOptions bag_options;
  app.add_option("--settings", args.settings_path, "settings YAML (config_yaml/*.yaml)");
  CLI::Option* sequence_option =
      app.add_option("--sequence", args.sequence_dir, "sequence folder (DATA_FORMAT.md, TUM RGB-D, OpenLORIS)");
  CLI::Option* bag_option = app.add_option("--bag", args.bag_path, "ROS 1 bag instead of --sequence");
  sequence_option->excludes(bag_option);
  bag_options.addTo(app);
  app.add_option("--calib", args.calib_path, "bag: calib.yaml (DATA_FORMAT.md) instead of CameraInfo");
  app.add_option("--groundtruth", args.groundtruth_path,
                 "bag: ground truth (TUM text, T_w_c) for metrics.json (a folder's is DIR/groundtruth.txt)");
  app.add_flag("--list-topics", args.list_topics, "with --bag: print the bag's topics, types, counts and rates");
  app.add_option("--out", args.out_dir, "output folder (created)");
  app.add_option("--vocabulary", args.vocabulary_path, "ORB vocabulary (default: the shipped one)");
  app.add_flag("--no-imu", args.no_imu, "ignore the IMU (RGB-D only; always so for rgbd)");
  app.add_flag("--single-thread", args.single_thread,
               "run local mapping and loop closing in the tracking thread (deterministic)");
  app.add_flag("--oracle-masks", args.oracle_masks,
               "diagnostic ablation: the sequence's ground-truth masks (masks/) replace the segmentation");
  app.add_option("--max-frames", args.max_frames, "stop after N frames (0: all)")->check(CLI::NonNegativeNumber);
  CLI::Option* first_frame_option =
      app.add_option("--first-frame", args.first_frame, "start at frame N of the sequence (0: the first)")
          ->check(CLI::NonNegativeNumber);
  app.add_option("--rate", args.rate,
                 "play the sequence at R times its recorded speed, as a live camera (frames wait for their stamps, "
                 "none is dropped; the summary counts late ones); 0: as fast as tracking goes")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--progress-every", args.progress_every, "progress line every N frames (0: none)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--set", args.overrides,
                 "Key=Value: replace one settings key, validated like the file (repeatable, e.g. "
                 "--set Seg.Enable=1 --set Seg.DenseInit=0)")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--viewer-video", args.viewer_video,
                 "live viewer: write its pictures (Viewer.Fps per second of sequence time) to this video (.avi MJPG, .mp4)");
  app.add_option("--viewer-dir", args.viewer_dir, "live viewer: write every picture as DIR/<frame>.png");
  app.add_option("--viewer-http", args.viewer_http,
                 "live viewer: serve it on this port (0: any free port; page /, MJPEG /stream.mjpg, /frame.jpg)")
      ->check(CLI::Range(0, 65535));
  app.add_option("--viewer-bind", args.viewer_bind, "address of the viewer's HTTP server (default 127.0.0.1; 0.0.0.0: every interface)");
  app.add_flag("--carried-variants", args.carried_variants,
               "also write trajectory_carried_none/blend/bridge.txt: the IMU-carried stretches as predicted, "
               "blended and bridged, from this one run");
  app.add_flag("--pose-stream", args.pose_stream,
               "publish every frame's pose as a JSON line on the viewer's HTTP server (/poses, server-sent events)");
  app.add_option("--save-atlas", args.save_atlas,
                 "write the maps to this atlas file at the end (also when stopped early), for --load-atlas");
  CLI::Option* load_atlas_option = app.add_option(
      "--load-atlas", args.load_atlas, "start in this saved atlas: relocalise in it, track in its world frame, extend it");
  app.add_flag("--localisation-only", args.localisation_only,
               "with --load-atlas: track in the loaded maps only, add no keyframe, point or map")
      ->needs(load_atlas_option);
  app.add_flag("--resume", args.resume,
               "with --load-atlas: continue the run that saved it at its next frame (its tracking, mapping and "
               "loop-closing state), instead of starting lost in its maps")
      ->needs(load_atlas_option);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  args.first_frame_given = first_frame_option->count() > 0;
  log::initFromEnvironment();
  if (args.pose_stream && args.viewer_http < 0) {
    std::fprintf(stderr, "%s: --pose-stream needs --viewer-http PORT (the poses are served at /poses)\n", kProgram);
    return 2;
  }
  try {
    if (args.list_topics) {
      if (args.bag_path.empty()) throw InputError("--list-topics needs --bag FILE");
      std::printf("%s", io::formatBagTopics(io::listBagTopics(args.bag_path)).c_str());
      return 0;
    }
    if (args.sequence_dir.empty() && args.bag_path.empty()) throw InputError("give --sequence DIR or --bag FILE");
    if (args.settings_path.empty()) throw InputError("--settings is required");
    if (args.out_dir.empty()) throw InputError("--out is required");
    if (!args.bag_path.empty()) {
      args.bag_topics = bag_options.resolve();
    } else if (!args.calib_path.empty() || !bag_options.preset.empty() || !args.groundtruth_path.empty()) {
      throw InputError("--calib, --bag-preset and --groundtruth are for --bag");
    }
    return run(args);
  } catch (const InputError& e) {
    std::fprintf(stderr, "%s: %s\n", kProgram, e.what());
    return 2;
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "%s: %s\n", kProgram, e.what());
    return 2;
  } catch (const bow::FileError& e) {
    std::fprintf(stderr, "%s: vocabulary: %s\n", kProgram, e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error: %s\n", kProgram, e.what());
    return 1;
  }
}
