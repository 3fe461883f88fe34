// bag_to_sequence: a ROS 1 bag as a sequence folder of DATA_FORMAT.md.
//
//   bag_to_sequence --bag FILE [--bag-preset tum|realsense|realsense-unite|openloris]
//                   [--rgb-topic T] [--depth-topic T] [--imu-topic T | --accel-topic T --gyro-topic T]
//                   [--camera-info-topic T] [--calib FILE] --out DIR [--force] [--progress-every N]
//
// Reads the bag with io::SequenceReader::openBag (the topics and the calibration as rgbd_inertial
// --bag reads them) and writes DIR/rgb/<t>.png (8-bit BGR), DIR/depth/<t>.png (16-bit, value =
// metres * DepthMapFactor of the calibration, 0 = no reading), rgb.txt, depth.txt,
// associations.txt, imu.txt (when the bag has IMU topics; the IMU's own stamps, i.e. before
// IMU.TimeOffset, which calib.yaml keeps) and calib.yaml (--calib FILE, else the bag's CameraInfo
// without IMU keys). Timestamps are the messages' header stamps, written so that they read back
// as the same doubles (6 decimals when that suffices). Each frame's colour and depth pair is the
// reader's association.
//
// Result lines on stdout: frames, imu_samples, wall_s, fps, outputs. Exit status: 0 done (also when
// interrupted by Ctrl-C: the frames so far are written with their index files), 2 bad input (the
// reader's message: bag, topic, message index; a non-empty --out without --force), 1 any other
// error. A bad message part-way keeps the frames written before it, with their index files.
#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "bag_topic_options.h"
#include "ltlo/core/calib.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/progress.h"
#include "ltlo/io/sequence_reader.h"

namespace {

using namespace ltlo;
namespace fs = std::filesystem;

constexpr const char* kProgram = "bag_to_sequence";

std::atomic<bool> g_stop_requested{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void onStopSignal(int signal_number) {
  g_stop_requested.store(true);
  std::signal(signal_number, SIG_DFL);  // a second Ctrl-C ends the program at once
}

struct Arguments {
  std::string bag_path;
  io::BagTopics topics;
  std::string calib_path;
  std::string out_dir;
  bool force = false;
  long progress_every = 100;
};

/// The shortest text that reads back (strtod) as the same double.
std::string shortestText(double value) {
  char buffer[64];
  const std::to_chars_result result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

/// Seconds as text that reads back (strtod) as the same double: "%.6f" when that is exact (the
/// DATA_FORMAT.md habit), else the shortest fixed-point text that is.
std::string stampText(double t_s) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.6f", t_s);
  if (std::strtod(buffer, nullptr) == t_s) return buffer;
  const std::to_chars_result result = std::to_chars(buffer, buffer + sizeof(buffer), t_s, std::chars_format::fixed);
  return std::string(buffer, result.ptr);
}

/// Metres (CV_32F, 0 or non-finite = no reading) as the 16-bit PNG values of DATA_FORMAT.md.
/// Depths beyond 65535 / factor cannot be stored: they become 0 and are counted.
cv::Mat depthToPngValues(const cv::Mat& depth_m, double depth_map_factor, long* num_out_of_range) {
  cv::Mat values(depth_m.size(), CV_16UC1);
  for (int v = 0; v < depth_m.rows; ++v) {
    const float* in = depth_m.ptr<float>(v);
    std::uint16_t* out = values.ptr<std::uint16_t>(v);
    for (int u = 0; u < depth_m.cols; ++u) {
      const double d_m = in[u];
      if (!(d_m > 0.0) || !std::isfinite(d_m)) {
        out[u] = 0;
        continue;
      }
      const long value = std::lround(d_m * depth_map_factor);
      if (value > 65535) {
        out[u] = 0;
        ++*num_out_of_range;
      } else {
        out[u] = static_cast<std::uint16_t>(value);
      }
    }
  }
  return values;
}

void writeImage(const fs::path& path, const cv::Mat& image) {
  if (!cv::imwrite(path.string(), image)) throw std::runtime_error(path.string() + ": cannot write the image");
}

std::ofstream openOutput(const fs::path& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot open for writing");
  return out;
}

/// --out is refused when it is a file, or a folder holding anything without --force (checked
/// before the bag is read: a long index read is not wasted, and bad input leaves no folder behind).
void checkOutput(const Arguments& args) {
  const fs::path out(args.out_dir);
  std::error_code error;
  if (!fs::exists(out, error)) return;
  if (!fs::is_directory(out, error)) throw InputError(args.out_dir, 0, "--out exists and is not a folder");
  if (!args.force && !fs::is_empty(out, error)) {
    throw InputError(args.out_dir, 0, "--out exists and is not empty (give --force to write into it)");
  }
}

/// Creates --out/rgb and --out/depth; with --force the files this program writes are removed
/// first (stale images would otherwise stay beside the new index), anything else stays.
void prepareOutput(const Arguments& args) {
  const fs::path out(args.out_dir);
  for (const char* name : {"rgb", "depth"}) fs::remove_all(out / name);
  for (const char* name : {"rgb.txt", "depth.txt", "associations.txt", "imu.txt", "calib.yaml"}) fs::remove(out / name);
  fs::create_directories(out / "rgb");
  fs::create_directories(out / "depth");
}

void writeImu(const fs::path& path, const io::SequenceReader& reader) {
  std::ofstream out = openOutput(path);
  out << "# timestamp gx gy gz ax ay az (s, rad/s, m/s^2), from " << reader.imuPath() << "\n";
  // The reader moved the stamps onto the camera clock by IMU.TimeOffset; calib.yaml keeps the
  // offset, so the file gets the IMU's own stamps back (reading it applies the offset once).
  const double offset_s = reader.calib().has_imu ? reader.calib().imu.time_offset_s : 0.0;
  for (const ImuSample& sample : reader.imu()) {
    out << stampText(sample.t_s + offset_s);
    for (const Vec3* triple : {&sample.gyro_rad_s, &sample.acc_m_s2}) {
      for (int i = 0; i < 3; ++i) out << ' ' << shortestText((*triple)(i));
    }
    out << '\n';
  }
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

struct WrittenFrame {
  std::string t_text, depth_t_text;
};

void writeIndexFiles(const fs::path& out_dir, const std::vector<WrittenFrame>& frames, const std::string& bag) {
  std::ofstream rgb = openOutput(out_dir / "rgb.txt");
  std::ofstream depth = openOutput(out_dir / "depth.txt");
  std::ofstream associations = openOutput(out_dir / "associations.txt");
  rgb << "# colour images of " << bag << "\n# timestamp filename\n";
  depth << "# depth images of " << bag << "\n# timestamp filename\n";
  associations << "# t_rgb rgb t_depth depth\n";
  std::string previous_depth;
  for (const WrittenFrame& frame : frames) {
    rgb << frame.t_text << " rgb/" << frame.t_text << ".png\n";
    // Two colour images may share one depth message: depth.txt lists each image once.
    if (frame.depth_t_text != previous_depth) depth << frame.depth_t_text << " depth/" << frame.depth_t_text << ".png\n";
    previous_depth = frame.depth_t_text;
    associations << frame.t_text << " rgb/" << frame.t_text << ".png " << frame.depth_t_text << " depth/"
                 << frame.depth_t_text << ".png\n";
  }
  if (!rgb || !depth || !associations) throw std::runtime_error(out_dir.string() + ": writing the index files failed");
}

int run(const Arguments& args) {
  const auto start = std::chrono::steady_clock::now();
  io::SequenceReaderOptions options;
  if (!args.calib_path.empty()) {
    if (!fs::is_regular_file(args.calib_path)) {
      throw InputError(args.calib_path, 0, "calibration file (--calib) does not exist");
    }
    options.calib_override = SensorCalib::load(args.calib_path);
    options.calib_override_source = args.calib_path;
  }
  checkOutput(args);
  io::SequenceReader reader = io::SequenceReader::openBag(args.bag_path, args.topics, options);
  prepareOutput(args);
  const fs::path out_dir(args.out_dir);
  const SensorCalib& calib = reader.calib();
  calib.write((out_dir / "calib.yaml").string());
  if (reader.hasImu()) {
    writeImu(out_dir / "imu.txt", reader);
    if (!calib.has_imu) {
      log::warn(kProgram, ": calib.yaml has no IMU.* keys (the calibration came from CameraInfo); add IMU.T_b_c1 "
                "and the noise keys, or give --calib FILE, before running rgbd_inertial on ", args.out_dir);
    }
  }

  const double factor = calib.camera.depth_map_factor;
  ProgressReporter progress({"frames", reader.frameCount(),
                             args.progress_every > 0 ? ProgressReporter::Style::kLines : ProgressReporter::Style::kSilent,
                             args.progress_every > 0 ? args.progress_every : 1});
  std::vector<WrittenFrame> written;
  long num_out_of_range = 0;
  std::string failure;
  int exit_code = 0;
  try {
    while (!g_stop_requested.load()) {
      std::optional<io::RgbdImuFrame> frame = reader.next();
      if (!frame) break;
      WrittenFrame names{stampText(frame->t_s), stampText(frame->depth_t_s)};
      writeImage(out_dir / "rgb" / (names.t_text + ".png"), frame->color_bgr);
      writeImage(out_dir / "depth" / (names.depth_t_text + ".png"),
                 depthToPngValues(frame->depth_m, factor, &num_out_of_range));
      written.push_back(names);
      progress.frameDone();
    }
  } catch (const InputError& e) {
    failure = e.what();
    exit_code = 2;
  }
  // Also after a bad message or Ctrl-C: the frames written so far get their index files.
  writeIndexFiles(out_dir, written, args.bag_path);
  progress.finish();
  if (num_out_of_range > 0) {
    log::warn(kProgram, ": ", num_out_of_range, " depth pixel(s) beyond ", 65535.0 / factor,
              " m (65535 / DepthMapFactor) written as 0 (no reading)");
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("frames %zu\nimu_samples %zu\nwall_s %.3f\nfps %.2f\noutputs %s\n", written.size(),
              reader.imu().size(), wall_s, wall_s > 0.0 ? written.size() / wall_s : 0.0, args.out_dir.c_str());
  std::fflush(stdout);
  if (!failure.empty()) {
    std::fprintf(stderr, "%s: %s\n%s: stopped after %zu of %d frames; those are written to %s\n", kProgram,
                 failure.c_str(), kProgram, written.size(), reader.frameCount(), args.out_dir.c_str());
  } else if (g_stop_requested.load()) {
    std::fprintf(stderr, "%s: interrupted after %zu of %d frames; those are written to %s\n", kProgram,
                 written.size(), reader.frameCount(), args.out_dir.c_str());
  }
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  std::signal(SIGINT, onStopSignal);
  std::signal(SIGTERM, onStopSignal);
  CLI::App app{"A ROS 1 bag as a sequence folder (DATA_FORMAT.md)"};
  Arguments args;
  examples::BagTopicOptions bag_options;
  app.add_option("--bag", args.bag_path, "ROS 1 bag");
  bag_options.addTo(app);
  app.add_option("--calib", args.calib_path, "calib.yaml (DATA_FORMAT.md) instead of the bag's CameraInfo");
  app.add_option("--out", args.out_dir, "output sequence folder (created; must be empty unless --force)");
  app.add_flag("--force", args.force, "write into a non-empty --out (its rgb/, depth/ and index files are replaced)");
  app.add_option("--progress-every", args.progress_every, "progress line every N frames (0: none)")
      ->check(CLI::NonNegativeNumber);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  log::initFromEnvironment();
  try {
    if (args.bag_path.empty()) throw InputError("--bag is required");
    if (args.out_dir.empty()) throw InputError("--out is required");
    args.topics = bag_options.resolve();
    return run(args);
  } catch (const InputError& e) {
    std::fprintf(stderr, "%s: %s\n", kProgram, e.what());
    return 2;
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "%s: %s\n", kProgram, e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error: %s\n", kProgram, e.what());
    return 1;
  }
}
