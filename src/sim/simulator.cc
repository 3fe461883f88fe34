#include "ltlo/sim/simulator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "lens_render.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"

namespace ltlo::sim {
namespace {

constexpr double kNearM = 0.05, kFarM = 30.0;
constexpr double kLargeOcclusion = 0.4;  // "largely occluded": more than 40 % dynamic pixels

std::string stamp(double t_s) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6f", t_s);
  return buffer;
}

TrajectoryParams trajectoryParams(const SimOptions& o) {
  TrajectoryParams p;
  p.mean_speed_mps = o.mean_speed_mps;
  p.vibration_angle_rad = o.vibration_angle_deg * M_PI / 180.0;
  p.vibration_height_m = o.vibration_height_m;
  p.stills = o.stills;
  return p;
}

// Frames handed from the renderer to the PNG writer thread (bounded, closed at the end).
class FrameQueue {
 public:
  explicit FrameQueue(size_t capacity) : capacity_(capacity) {}
  void push(SimFrame frame) {
    std::unique_lock<std::mutex> lock(mutex_);
    not_full_.wait(lock, [&] { return queue_.size() < capacity_; });
    queue_.push_back(std::move(frame));
    not_empty_.notify_one();
  }
  bool pop(SimFrame* frame) {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return !queue_.empty() || closed_; });
    if (queue_.empty()) return false;
    *frame = std::move(queue_.front());
    queue_.pop_front();
    not_full_.notify_one();
    return true;
  }
  void close() {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
    not_empty_.notify_all();
  }

 private:
  size_t capacity_;
  std::mutex mutex_;
  std::condition_variable not_full_, not_empty_;
  std::deque<SimFrame> queue_;
  bool closed_ = false;
};

void writePng(const std::string& path, const cv::Mat& image, int compression) {
  // Run-length strategy: smaller and faster than the default deflate on noisy images. Level 1 is
  // requested by leaving the level unset: OpenCV then takes its speed path (zlib level 1 with the
  // single SUB filter instead of libpng's adaptive filter search), about twice as fast.
  std::vector<int> params = {cv::IMWRITE_PNG_STRATEGY, cv::IMWRITE_PNG_STRATEGY_RLE};
  if (compression != 1)
    params = {cv::IMWRITE_PNG_COMPRESSION, compression, cv::IMWRITE_PNG_STRATEGY,
              cv::IMWRITE_PNG_STRATEGY_RLE};
  if (!cv::imwrite(path, image, params)) {
    throw InputError(path, 0, "cannot write PNG");
  }
}

std::ofstream openText(const std::string& path) {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  return out;
}

int numFramesOf(const SimOptions& options) {
  return static_cast<int>(std::floor(options.duration_s * options.fps - 1e-9)) + 1;
}

double frameTimeOf(const SimOptions& options, int index) {
  return std::round(index / options.fps * 1e6) * 1e-6;
}

SensorTruth drawTruth(const SimOptions& options) {
  std::vector<double> frame_times(numFramesOf(options));
  for (size_t i = 0; i < frame_times.size(); ++i) frame_times[i] = frameTimeOf(options, static_cast<int>(i));
  return drawSensorTruth(options.sensor, options.seed, SimOptions::T_b_c(), options.imu_rate_hz, frame_times);
}

ImuFaults imuFaults(const SensorProfile& profile, const SensorTruth& truth) {
  ImuFaults faults;
  faults.time_offset_s = truth.time_offset_s;
  faults.intrinsics = profile.imu_intrinsics_enable;
  faults.M_gyro = truth.M_gyro;
  faults.M_acc = truth.M_acc;
  faults.jitter_s = profile.jitter_enable ? profile.imu_jitter_s : 0.0;
  faults.separate_clocks = profile.imu_clocks_enable;
  faults.gyro_rate_hz = truth.gyro_rate_hz;
  faults.acc_rate_hz = truth.acc_rate_hz;
  faults.acc_phase_s = truth.acc_phase_s;
  faults.merged_rows = profile.merged_rows;
  return faults;
}

// A lens or a rolling shutter needs the raw-frame renderer; the pinhole global shutter renders directly.
std::unique_ptr<RawFrameRenderer> makeRawRenderer(const SimOptions& options, const SensorTruth& truth) {
  const SensorProfile& profile = options.sensor;
  if (!truth.lens.isDistorted() && !profile.rolling_shutter_enable) return nullptr;
  return std::make_unique<RawFrameRenderer>(CameraModel(options.camera(), truth.lens),
                                            profile.rolling_shutter_enable ? profile.readout_s : 0.0,
                                            profile.rolling_shutter_bands);
}

}  // namespace

Simulator::Simulator(const SimOptions& options)
    : Simulator(options, Scene::buildRoom(options.texture_dir)) {}

Simulator::Simulator(const SimOptions& options, Scene room)
    : options_(options),
      camera_(options.camera()),
      trajectory_(trajectoryParams(options), options.seed),
      scene_(std::move(room)),
      truth_(drawTruth(options)),
      imu_(simulateImu(trajectory_, options, imuFaults(options.sensor, truth_))),
      raw_renderer_(makeRawRenderer(options, truth_)),
      renderer_(std::make_unique<render::OffscreenRenderer>(
          raw_renderer_ ? raw_renderer_->bufferWidth() : options.width_px,
          raw_renderer_ ? raw_renderer_->bufferHeight() : options.height_px)) {
  scene_.scheduleOcclusions(options_);
  for (const cv::Mat& texture : scene_.textures) renderer_->addTexture(texture);
  for (const render::Mesh& mesh : scene_.static_meshes)
    static_items_.push_back({renderer_->addMesh(mesh), SE3(), 1.0f, 0});
  for (const render::Mesh& mesh : scene_.door_frames)
    static_items_.push_back({renderer_->addMesh(mesh), SE3(), 1.0f, 0});
  for (const std::vector<render::Mesh>& parts : scene_.moverMeshes()) {
    mover_drawables_.emplace_back();
    for (const render::Mesh& mesh : parts) mover_drawables_.back().push_back(renderer_->addMesh(mesh));
  }
  exposure_phase_ = std::fmod(static_cast<double>(options.seed) * 0.618034, 1.0) * 2.0 * M_PI;
}

Simulator::~Simulator() = default;

int Simulator::numFrames() const { return numFramesOf(options_); }

double Simulator::frameTime(int index) const { return frameTimeOf(options_, index); }

SensorCalib Simulator::calib() const {
  SensorCalib calib = options_.sensorCalib();
  const SensorProfile& profile = options_.sensor;
  if (profile.isIdeal()) return calib;
  calib.camera.lens = truth_.lens;
  calib.imu.T_b_c = truth_.T_b_c_calib;
  calib.imu.rate_hz = truth_.gyro_rate_hz;  // readers merge the accelerometer onto the gyroscope's stamps
  // The offset is unknown to the user unless the profile says the calibration found it.
  if (profile.time_offset_enable && profile.time_offset_in_calib) calib.imu.time_offset_s = truth_.time_offset_s;
  return calib;
}

SE3 Simulator::T_w_c(double t_s) const {
  return trajectory_.state(t_s).T_w_b * SimOptions::T_b_c();
}

io::Trajectory Simulator::groundTruth() const {
  io::Trajectory gt;
  for (int i = 0; i < numFrames(); ++i)
    if (!frameDropped(i)) gt.push_back({frameStamp(i), T_w_c(frameTime(i))});
  return gt;
}

std::vector<render::DrawItem> Simulator::dynamicItems(double t_s) const {
  std::vector<render::DrawItem> items;
  for (const MoverPart& part : scene_.moverParts(t_s, trajectory_)) {
    items.push_back({mover_drawables_[part.mover][part.part], part.T_w_o, 1.0f,
                     static_cast<uint8_t>(std::min(part.mover + 1, 255))});
  }
  return items;
}

std::vector<render::DrawItem> Simulator::itemsAt(double t_s, float gain, bool with_static,
                                                 bool with_dynamic) const {
  std::vector<render::DrawItem> items;
  if (with_static) items = static_items_;
  if (with_dynamic)
    for (render::DrawItem item : dynamicItems(t_s)) items.push_back(item);
  for (render::DrawItem& item : items) item.gain = gain;
  return items;
}

render::RenderResult Simulator::renderRaw(double t_s, float gain, bool with_static, bool with_dynamic) {
  if (!raw_renderer_)
    return renderer_->render({camera_, T_w_c(t_s).inverse(), kNearM, kFarM},
                             itemsAt(t_s, gain, with_static, with_dynamic));
  const auto view_at = [&](double t_row_s) {
    return RawFrameRenderer::View{T_w_c(t_row_s).inverse(), itemsAt(t_row_s, gain, with_static, with_dynamic)};
  };
  return raw_renderer_->render(*renderer_, t_s, view_at, kNearM, kFarM);
}

SimFrame Simulator::renderFrame(int index) {
  const double t_s = frameTime(index);
  const SE3 T_w_c_now = T_w_c(t_s);
  float gain = options_.noise_free
                   ? 1.0f
                   : static_cast<float>(1.0 + options_.exposure_jitter *
                                                  std::sin(2.0 * M_PI * t_s / 7.0 + exposure_phase_));
  // Auto-exposure scales the light reaching the sensor: the renderer's gain saturates at white.
  if (options_.sensor.exposure_enable) gain = static_cast<float>(gain * truth_.exposureGain(t_s));
  const auto t0 = std::chrono::steady_clock::now();
  const render::RenderResult clean = renderRaw(t_s, gain, true, true);
  const auto t1 = std::chrono::steady_clock::now();
  SimFrame frame = addSensorEffects(index, clean);
  render_time_s_ += std::chrono::duration<double>(t1 - t0).count();
  effects_time_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  frame.t_s = frameStamp(index);
  frame.t_true_s = t_s;
  frame.gain = gain;
  frame.T_w_c = T_w_c_now;
  for (const SensorOutage& outage : options_.outages) {
    if (!outage.covers(t_s) || outage.kind == SensorOutage::Kind::kImuGap) continue;
    if (outage.kind == SensorOutage::Kind::kBlack) frame.bgr.setTo(cv::Scalar::all(0));
    frame.depth_m.setTo(0.0f);
    frame.depth_raw.setTo(0);
  }
  return frame;
}

render::RenderResult Simulator::renderDynamicOnly(int index) {
  return renderRaw(frameTime(index), 1.0f, false, true);
}

render::RenderResult Simulator::renderStaticOnly(int index) {
  return renderRaw(frameTime(index), 1.0f, true, false);
}

SimFrame Simulator::addSensorEffects(int index, const render::RenderResult& clean) const {
  const SimOptions& o = options_;
  const int rows = clean.depth_m.rows, cols = clean.depth_m.cols;
  cv::RNG rng(o.seed * 1000003ULL + static_cast<uint64_t>(index) * 7919ULL + 1);
  SimFrame frame;
  cv::compare(clean.labels, 0, frame.mask, cv::CMP_GT);  // 255 where a box is visible
  frame.dynamic_fraction = cv::countNonZero(frame.mask) / static_cast<double>(rows * cols);

  if (o.noise_free || o.rgb_noise_sigma <= 0.0) {
    frame.bgr = clean.bgr;
  } else {
    cv::Mat noise(rows, cols, CV_16SC3);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, o.rgb_noise_sigma);
    cv::add(clean.bgr, noise, frame.bgr, cv::noArray(), CV_8UC3);
  }

  cv::Mat depth = clean.depth_m.clone();
  if (!o.noise_free) {
    cv::Mat gauss(rows, cols, CV_32F), uniform(rows, cols, CV_32F);
    rng.fill(gauss, cv::RNG::NORMAL, 0.0, 1.0);
    rng.fill(uniform, cv::RNG::UNIFORM, 0.0, 1.0);
    // Depth edges: a 4-neighbour jump larger than 4 cm + 2 % of the depth, grown by one pixel.
    cv::Mat edges = cv::Mat::zeros(rows, cols, CV_8U);
    for (int v = 0; v < rows; ++v) {
      const float* z = clean.depth_m.ptr<float>(v);
      const float* z_down = v + 1 < rows ? clean.depth_m.ptr<float>(v + 1) : nullptr;
      uint8_t* e = edges.ptr<uint8_t>(v);
      uint8_t* e_down = v + 1 < rows ? edges.ptr<uint8_t>(v + 1) : nullptr;
      for (int u = 0; u < cols; ++u) {
        const float threshold = 0.04f + 0.02f * z[u];
        if (u + 1 < cols && std::abs(z[u + 1] - z[u]) > threshold) e[u] = e[u + 1] = 255;
        if (z_down && std::abs(z_down[u] - z[u]) > threshold) e[u] = e_down[u] = 255;
      }
    }
    cv::dilate(edges, edges, cv::Mat::ones(3, 3, CV_8U));
    const float k = static_cast<float>(o.depth_noise_at_1m_m);
    const float p_edge = static_cast<float>(o.depth_edge_dropout);
    const float p_random = static_cast<float>(o.depth_random_dropout);
    for (int v = 0; v < rows; ++v) {
      float* z = depth.ptr<float>(v);
      const float* g = gauss.ptr<float>(v);
      const float* r = uniform.ptr<float>(v);
      const uint8_t* e = edges.ptr<uint8_t>(v);
      for (int u = 0; u < cols; ++u) {
        const bool drop = e[u] ? r[u] < p_edge : r[u] > 1.0f - p_random;
        z[u] = drop ? 0.0f : z[u] + k * z[u] * z[u] * g[u];
      }
    }
  }
  frame.depth_raw.create(rows, cols, CV_16U);
  frame.depth_m.create(rows, cols, CV_32F);
  const double factor = o.depth_map_factor;
  for (int v = 0; v < rows; ++v) {
    const float* z = depth.ptr<float>(v);
    uint16_t* raw = frame.depth_raw.ptr<uint16_t>(v);
    float* out = frame.depth_m.ptr<float>(v);
    for (int u = 0; u < cols; ++u) {
      const bool valid = z[u] >= o.depth_min_m && z[u] <= o.depth_max_m;
      const double value = valid ? std::round(z[u] * factor) : 0.0;
      raw[u] = static_cast<uint16_t>(std::min(value, 65535.0));
      out[u] = static_cast<float>(raw[u] / factor);
    }
  }
  return frame;
}

SequenceStats writeSequence(const SimOptions& options, const std::string& out_dir,
                            int progress_every) {
  const auto start = std::chrono::steady_clock::now();
  Simulator sim(options);
  SequenceStats stats = writeSequence(sim, out_dir, progress_every);
  stats.frames_per_s =
      stats.num_frames /
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  log::info("simulate: ", stats.frames_per_s, " frames/s including scene set-up");
  return stats;
}

std::uintmax_t expectedSequenceBytes(const SimOptions& options) {
  constexpr double kVgaFrameBytes = 0.9e6;  // colour + depth + mask PNGs, photo-textured scenes
  constexpr double kMargin = 1.25;
  const double pixels = static_cast<double>(options.width_px) * options.height_px;
  return static_cast<std::uintmax_t>(kMargin * kVgaFrameBytes * numFramesOf(options) * pixels / (640.0 * 480.0));
}

void requireFreeSpace(const std::string& out_dir, std::uintmax_t bytes) {
  namespace fs = std::filesystem;
  std::error_code error;
  fs::path existing = fs::absolute(fs::path(out_dir), error);
  if (error) return;  // no answer from the file system: the writes themselves report a full disk
  while (!fs::exists(existing, error) && existing.has_parent_path() && existing != existing.parent_path()) {
    existing = existing.parent_path();
  }
  const fs::space_info space = fs::space(existing, error);
  if (error) return;  // no answer from the file system: the writes themselves report a full disk
  if (space.available >= bytes) return;
  const auto gb = [](std::uintmax_t b) {
    char text[32];
    std::snprintf(text, sizeof(text), "%.2f GB", static_cast<double>(b) / 1e9);
    return std::string(text);
  };
  throw InputError(out_dir, 0,
                   "the sequence needs about " + gb(bytes) + " and its file system has " + gb(space.available) +
                       " available (free space, or a shorter --seconds or smaller --width/--height)");
}

namespace {

void createSequenceFolders(const std::string& out_dir) {
  namespace fs = std::filesystem;
  std::error_code error;
  for (const char* sub : {"rgb", "depth", "masks"}) {
    fs::create_directories(fs::path(out_dir) / sub, error);
    if (error)
      throw InputError(out_dir, 0,
                       "cannot create directory " + std::string(sub) + ": " + error.message());
  }
}

void logSequenceStart(const Simulator& sim) {
  const SimOptions& options = sim.options();
  log::info("simulate: scenario ", scenarioName(options.scenario), ", seed ", options.seed, ", ",
            options.duration_s, " s at ", options.fps, " fps, ", options.width_px, "x",
            options.height_px, options.noise_free ? ", noise-free" : "", ", textures: ",
            sim.scene().photo_textures
                ? std::to_string(sim.scene().photo_paths.size()) + " photographs"
                : "procedural",
            ", ", sim.scene().boxes.size(), " dynamic boxes, ", sim.scene().walkers.size(), " walkers, ",
            sim.scene().doors.size(), " doors");
}

bool inImuGap(const SimOptions& options, double t_s) {
  return std::any_of(options.outages.begin(), options.outages.end(), [t_s](const SensorOutage& o) {
    return o.kind == SensorOutage::Kind::kImuGap && o.covers(t_s);
  });
}

// imu.txt (the samples outside IMU gaps, nan for a sensor without a sample at the stamp) and
// imu_biases.txt (the true biases at every sample, gaps included).
void writeImuFiles(const Simulator& sim, const std::string& dir) {
  const SimOptions& options = sim.options();
  const SensorProfile& profile = options.sensor;
  std::ofstream imu = openText(dir + "imu.txt");
  std::ofstream biases = openText(dir + "imu_biases.txt");
  imu << "# timestamp gx gy gz ax ay az (s, rad/s, m/s^2, body frame)\n";
  if (profile.imu_clocks_enable && !profile.merged_rows)
    imu << "# gyroscope and accelerometer on their own clocks: nan = that sensor has no sample at this stamp\n";
  biases << "# timestamp bgx bgy bgz bax bay baz (true biases, ground truth)\n";
  char line[256];
  for (const ImuSample& s : sim.imu()) {
    if (!inImuGap(options, s.t_s)) {
      if (s.has_gyro && s.has_acc) {
        std::snprintf(line, sizeof(line), "%.6f %.9f %.9f %.9f %.9f %.9f %.9f\n", s.t_s,
                      s.gyro_rad_s.x(), s.gyro_rad_s.y(), s.gyro_rad_s.z(), s.acc_mps2.x(),
                      s.acc_mps2.y(), s.acc_mps2.z());
      } else if (s.has_gyro) {
        std::snprintf(line, sizeof(line), "%.6f %.9f %.9f %.9f nan nan nan\n", s.t_s, s.gyro_rad_s.x(),
                      s.gyro_rad_s.y(), s.gyro_rad_s.z());
      } else {
        std::snprintf(line, sizeof(line), "%.6f nan nan nan %.9f %.9f %.9f\n", s.t_s, s.acc_mps2.x(),
                      s.acc_mps2.y(), s.acc_mps2.z());
      }
      imu << line;
    }
    std::snprintf(line, sizeof(line), "%.6f %.9f %.9f %.9f %.9f %.9f %.9f\n", s.t_s,
                  s.bias_gyro.x(), s.bias_gyro.y(), s.bias_gyro.z(), s.bias_acc.x(),
                  s.bias_acc.y(), s.bias_acc.z());
    biases << line;
  }
  if (!imu || !biases) throw InputError(dir + "imu.txt", 0, "write failed");
}

// rgb.txt, depth.txt and associations.txt: one line per written frame.
class FrameIndexFiles {
 public:
  FrameIndexFiles(const std::string& dir, double depth_map_factor)
      : rgb_txt_(openText(dir + "rgb.txt")),
        depth_txt_(openText(dir + "depth.txt")),
        assoc_txt_(openText(dir + "associations.txt")) {
    rgb_txt_ << "# colour images\n# timestamp filename\n";
    depth_txt_ << "# depth images (16-bit, metres = value / " << depth_map_factor
               << ")\n# timestamp filename\n";
    assoc_txt_ << "# t_rgb rgb t_depth depth\n";
  }
  void add(const std::string& name) {
    rgb_txt_ << name << " rgb/" << name << ".png\n";
    depth_txt_ << name << " depth/" << name << ".png\n";
    assoc_txt_ << name << " rgb/" << name << ".png " << name << " depth/" << name << ".png\n";
  }

 private:
  std::ofstream rgb_txt_, depth_txt_, assoc_txt_;
};

// PNG encoding runs on two writer threads; file contents never depend on their timing.
class PngWriters {
 public:
  PngWriters(const std::string& dir, int png_compression) : dir_(dir), png_compression_(png_compression) {
    for (int worker = 0; worker < 2; ++worker) writers_.emplace_back(&PngWriters::writeFrames, this, worker);
  }
  void push(SimFrame frame) { queue_.push(std::move(frame)); }
  /// Closes the queue and waits until the writers have written everything queued.
  void join() {
    queue_.close();
    for (std::thread& writer : writers_) writer.join();
  }
  /// The first error a writer met (after join()).
  void rethrowError() const {
    if (writer_error_) std::rethrow_exception(writer_error_);
  }
  double pngTimeS() const { return png_time_s_[0] + png_time_s_[1]; }

 private:
  void writeFrames(int worker) {
    log::setThreadName("png" + std::to_string(worker));
    SimFrame frame;
    while (queue_.pop(&frame)) {
      try {
        const auto t0 = std::chrono::steady_clock::now();
        const std::string name = stamp(frame.t_s) + ".png";
        writePng(dir_ + "rgb/" + name, frame.bgr, png_compression_);
        writePng(dir_ + "depth/" + name, frame.depth_raw, png_compression_);
        writePng(dir_ + "masks/" + name, frame.mask, png_compression_);
        png_time_s_[worker] +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex_);
        if (!writer_error_) writer_error_ = std::current_exception();
      }
    }
  }

  const std::string dir_;
  const int png_compression_;
  FrameQueue queue_{6};
  std::mutex error_mutex_;
  std::exception_ptr writer_error_;
  std::vector<double> png_time_s_ = std::vector<double>(2, 0.0);
  std::vector<std::thread> writers_;  // last: the threads start once the members above exist
};

// Dynamic-share statistics over the written frames.
struct OcclusionTally {
  int occluded = 0, run = 0, longest_run = 0;
  double dynamic_sum = 0.0, present_sum = 0.0;
  int present = 0;

  void add(double dynamic_fraction) {
    dynamic_sum += dynamic_fraction;
    if (dynamic_fraction > 0.01) {
      ++present;
      present_sum += dynamic_fraction;
    }
    if (dynamic_fraction > kLargeOcclusion) {
      ++occluded;
      longest_run = std::max(longest_run, ++run);
    } else {
      run = 0;
    }
  }
};

// Renders every frame the driver does not drop, indexes it and queues it for the PNG writers.
void renderFrames(Simulator& sim, int progress_every, FrameIndexFiles* index, PngWriters* writers,
                  SequenceStats* stats, std::vector<WrittenFrame>* written, OcclusionTally* tally) {
  const SensorProfile& profile = sim.options().sensor;
  auto last_report = std::chrono::steady_clock::now();
  for (int i = 0; i < sim.numFrames(); ++i) {
    if (sim.frameDropped(i)) {  // never rendered: the driver lost it
      ++stats->num_dropped;
      continue;
    }
    ++stats->num_frames;
    SimFrame frame = sim.renderFrame(i);
    if (!profile.isIdeal()) written->push_back({i, frame.t_s, frame.t_true_s, frame.gain});
    index->add(stamp(frame.t_s));
    tally->add(frame.dynamic_fraction);
    writers->push(std::move(frame));
    if (progress_every > 0 && (i + 1) % progress_every == 0) {
      const auto now = std::chrono::steady_clock::now();
      const double dt = std::chrono::duration<double>(now - last_report).count();
      log::info("frame ", i + 1, "/", sim.numFrames(), ", ", progress_every / std::max(dt, 1e-9),
                " fps");
      last_report = now;
    }
  }
}

// The options of issue 32's harder worlds, one line each when used (without them stats.txt is what
// it always was).
void writeHarderWorldStats(const Simulator& sim, std::ostream& out) {
  const SimOptions& options = sim.options();
  const Scene& scene = sim.scene();
  if (options.plain_movers) {
    const auto panels = std::count_if(scene.boxes.begin(), scene.boxes.end(), [](const DynamicBox& b) { return b.panel; });
    out << "\nplain_movers 1 (" << panels << " of " << scene.boxes.size() << " boxes are "
        << (options.tall_panels ? "tall panels" : "panels") << ")";
  }
  for (const DynamicBox& b : scene.boxes)
    if (b.start_move != StartMove::kNone)
      out << "\noccluded_start " << (b.start_move == StartMove::kAway ? "away" : "towards") << " (moves at "
          << b.t_move_s << " s, gone at " << b.t_out_s << " s, near face " << b.distance_m << " m)";
  if (options.walkers > 0) {
    const auto leading = std::count_if(scene.walkers.begin(), scene.walkers.end(),
                                       [](const Walker& w) { return w.kind == Walker::Kind::kLeading; });
    out << "\nwalkers " << scene.walkers.size() << " (" << leading << " leading, " << scene.walkers.size() - leading
        << " crossing)";
  }
  if (options.doors) out << "\ndoors " << scene.doors.size();
  if (options.three_movers) out << "\nthree_movers 1";
}

void writeStatsFile(const Simulator& sim, const SequenceStats& stats, const std::string& dir) {
  const SimOptions& options = sim.options();
  const SensorProfile& profile = options.sensor;
  std::ofstream out = openText(dir + "stats.txt");
  out << "scenario " << scenarioName(options.scenario) << "\nseed " << options.seed
      << "\nduration_s " << stats.duration_s << "\nnum_frames " << stats.num_frames << "\nfps "
      << options.fps << "\nresolution " << options.width_px << "x" << options.height_px
      << "\npath_length_m " << stats.path_length_m << "\noccluded_share_gt40 "
      << stats.occluded_share << "\nmean_dynamic_fraction " << stats.mean_dynamic_fraction
      << "\nmean_dynamic_fraction_when_present " << stats.mean_fraction_when_present
      << "\nlongest_occlusion_s " << stats.longest_occlusion_s << "\nnum_dynamic_boxes "
      << sim.scene().boxes.size() << "\nnoise_free " << (options.noise_free ? 1 : 0)
      << "\nimu_rate_hz " << options.imu_rate_hz << "\nimu_noise_gyro " << options.noise_gyro
      << "\nimu_noise_acc " << options.noise_acc << "\nimu_gyro_walk " << options.gyro_walk
      << "\nimu_acc_walk " << options.acc_walk << "\nimu_gyro_bias_init_std "
      << options.gyro_bias_init << "\nimu_acc_bias_init_std " << options.acc_bias_init
      << "\ndepth_range_m " << options.depth_min_m << " " << options.depth_max_m
      << "\ndepth_noise_at_1m_m " << options.depth_noise_at_1m_m << " (std grows with z^2)"
      << "\ndepth_edge_dropout " << options.depth_edge_dropout << "\ndepth_random_dropout "
      << options.depth_random_dropout << "\nrgb_noise_sigma " << options.rgb_noise_sigma
      << "\nexposure_jitter " << options.exposure_jitter;
  if (!profile.isIdeal())
    out << "\nsensor " << profile.describe() << " (" << stats.num_dropped << " of " << sim.numFrames()
        << " frames dropped; true values in sensor_truth.yaml)";
  writeHarderWorldStats(sim, out);
  out << "\ntextures "
      << (sim.scene().photo_textures ? "photographs" : "procedural") << "\n";
  for (const std::string& path : sim.scene().photo_paths) out << "texture_photo " << path << "\n";
  if (!out) throw InputError(dir + "stats.txt", 0, "write failed");
}

}  // namespace

SequenceStats writeSequence(Simulator& sim, const std::string& out_dir, int progress_every) {
  const SimOptions& options = sim.options();
  const auto start = std::chrono::steady_clock::now();
  requireFreeSpace(out_dir, expectedSequenceBytes(options));
  createSequenceFolders(out_dir);
  logSequenceStart(sim);

  const SensorProfile& profile = options.sensor;
  if (!profile.isIdeal()) log::info("simulate: sensor ", profile.describe());
  const std::string dir = out_dir + "/";
  sim.calib().write(dir + "calib.yaml");
  io::writeTumTrajectory(dir + "groundtruth.txt", sim.groundTruth());
  sim.scene().writePly(dir + "scene.ply");
  writeImuFiles(sim, dir);

  FrameIndexFiles index(dir, options.depth_map_factor);
  PngWriters writers(dir, options.png_compression);
  SequenceStats stats;
  stats.duration_s = options.duration_s;
  std::vector<WrittenFrame> written;
  OcclusionTally tally;
  try {
    renderFrames(sim, progress_every, &index, &writers, &stats, &written, &tally);
  } catch (...) {
    writers.join();
    throw;
  }
  writers.join();
  writers.rethrowError();

  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats.path_length_m = sim.trajectory().pathLength(options.duration_s);
  stats.occluded_share = tally.occluded / static_cast<double>(stats.num_frames);
  stats.mean_dynamic_fraction = tally.dynamic_sum / stats.num_frames;
  stats.longest_occlusion_s = tally.longest_run / options.fps;
  stats.mean_fraction_when_present = tally.present > 0 ? tally.present_sum / tally.present : 0.0;
  stats.frames_per_s = stats.num_frames / elapsed_s;

  writeStatsFile(sim, stats, dir);
  if (!profile.isIdeal()) {
    std::vector<double> frame_times(sim.numFrames());
    for (int i = 0; i < sim.numFrames(); ++i) frame_times[i] = sim.frameTime(i);
    writeSensorTruth(dir + "sensor_truth.yaml", profile, sim.sensorTruth(), written, frame_times);
  }
  log::info("simulate: wrote ", stats.num_frames, " frames to ", out_dir, " in ", elapsed_s, " s (",
            stats.frames_per_s, " frames/s after set-up); path ", stats.path_length_m,
            " m; frames > 40 % dynamic: ", 100.0 * stats.occluded_share, " % (mean ",
            100.0 * stats.mean_fraction_when_present, " % of the image when present), longest ",
            stats.longest_occlusion_s, " s");
  log::info("simulate: per frame ", 1e3 * sim.renderTimeS() / stats.num_frames, " ms render, ",
            1e3 * sim.effectsTimeS() / stats.num_frames, " ms sensor effects, ",
            1e3 * writers.pngTimeS() / stats.num_frames, " ms PNG (2 writer threads)");
  return stats;
}

}  // namespace ltlo::sim
