#pragma once
/// Synthetic RGB-D-inertial sequence generator (issue 3): renders the room and the scenario's
/// dynamic boxes along the robot trajectory, adds sensor effects and writes DATA_FORMAT.md.
/// A sensor profile (SimOptions::sensor, sensor_profile.h) adds the faults of a real sensor; with the
/// ideal profile every output is exactly what the simulator wrote before profiles existed.
#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "ltlo/io/trajectory_io.h"
#include "ltlo/render/offscreen_renderer.h"
#include "ltlo/sim/imu_simulator.h"
#include "ltlo/sim/robot_trajectory.h"
#include "ltlo/sim/scene.h"
#include "ltlo/sim/sensor_profile.h"
#include "ltlo/sim/sim_options.h"

namespace ltlo::sim {

class RawFrameRenderer;  // src/sim/lens_render.h

struct SimFrame {
  double t_s = 0.0;       ///< stamp as written (the true instant plus the profile's jitter)
  double t_true_s = 0.0;  ///< instant the image was taken (its centre row with a rolling shutter)
  double gain = 1.0;      ///< colour gain applied (exposure jitter times the profile's auto-exposure)
  SE3 T_w_c;              ///< true camera pose at t_true_s
  cv::Mat bgr;        ///< CV_8UC3 with exposure jitter and noise (unless noise-free)
  cv::Mat depth_m;    ///< CV_32F metres after noise, holes and range limits; 0 = no reading
  cv::Mat depth_raw;  ///< CV_16U as written (metres * DepthMapFactor)
  cv::Mat mask;       ///< CV_8U, 255 where a dynamic object is the visible surface
  double dynamic_fraction = 0.0;
};

/// Summary of a written sequence (also in stats.txt).
struct SequenceStats {
  int num_frames = 0;  ///< frames written (dropped frames are not)
  int num_dropped = 0;
  double duration_s = 0.0;
  double path_length_m = 0.0;
  double occluded_share = 0.0;  ///< frames with more than 40 % dynamic pixels
  double mean_dynamic_fraction = 0.0;
  double mean_fraction_when_present = 0.0;  ///< over frames with more than 1 % dynamic pixels
  double longest_occlusion_s = 0.0;         ///< longest run of frames above 40 %
  double frames_per_s = 0.0;                ///< generation speed (wall clock)
};

class Simulator {
 public:
  explicit Simulator(const SimOptions& options);
  /// Reuses a room from Scene::buildRoom (loading photographs is the slow part of construction);
  /// its dynamic boxes are rescheduled for `options`.
  Simulator(const SimOptions& options, Scene room);
  ~Simulator();

  const SimOptions& options() const { return options_; }
  const Scene& scene() const { return scene_; }
  const RobotTrajectory& trajectory() const { return trajectory_; }
  /// The ideal pinhole camera of the configured K (what the renderer sees before the lens).
  const PinholeCamera& camera() const { return camera_; }
  /// The raw camera: K with the profile's lens (no lens: the pinhole).
  CameraModel cameraModel() const { return CameraModel(camera_, truth_.lens); }
  /// IMU samples in stamp order (half rows when the profile puts gyro and accelerometer on own clocks).
  const std::vector<ImuSample>& imu() const { return imu_; }
  /// The faults drawn for this sequence (the true sensor; ideal: none).
  const SensorTruth& sensorTruth() const { return truth_; }
  /// calib.yaml content: the configuration's calibration with the profile's lens, its erroneous
  /// extrinsic, the gyroscope's rate and (when the profile says so) the true time offset.
  SensorCalib calib() const;

  /// Frames of the camera clock (dropped ones included).
  int numFrames() const;
  /// True instant of frame `index`: i / fps rounded to microseconds (exact in the 6-decimal names).
  double frameTime(int index) const;
  /// Stamp written for frame `index` (frameTime plus the profile's jitter).
  double frameStamp(int index) const { return truth_.camera_stamp_s[index]; }
  /// Whether the profile drops frame `index` (not written; the IMU runs on).
  bool frameDropped(int index) const { return truth_.dropped[index] != 0; }
  SE3 T_w_c(double t_s) const;
  /// Written frames: (stamp, true pose of the instant the image was taken).
  io::Trajectory groundTruth() const;

  SimFrame renderFrame(int index);
  /// Only the movers (label = mover index + 1, Scene::moverParts), noise-free depth: for mask checks.
  render::RenderResult renderDynamicOnly(int index);
  /// Only the static room, noise-free.
  render::RenderResult renderStaticOnly(int index);

  /// Wall-clock seconds spent in renderFrame: OpenGL rendering and read-back, sensor effects.
  double renderTimeS() const { return render_time_s_; }
  double effectsTimeS() const { return effects_time_s_; }

 private:
  std::vector<render::DrawItem> dynamicItems(double t_s) const;
  std::vector<render::DrawItem> itemsAt(double t_s, float gain, bool with_static, bool with_dynamic) const;
  /// The raw image at true time t_s: the ideal renderer, or through the lens / rolling shutter.
  render::RenderResult renderRaw(double t_s, float gain, bool with_static, bool with_dynamic);
  SimFrame addSensorEffects(int index, const render::RenderResult& clean) const;

  SimOptions options_;
  PinholeCamera camera_;
  RobotTrajectory trajectory_;
  Scene scene_;
  SensorTruth truth_;
  std::vector<ImuSample> imu_;
  std::unique_ptr<RawFrameRenderer> raw_renderer_;  ///< null for a pinhole global-shutter camera
  std::unique_ptr<render::OffscreenRenderer> renderer_;
  std::vector<render::DrawItem> static_items_;
  std::vector<std::vector<int>> mover_drawables_;  ///< per mover (Scene::moverMeshes) its parts' drawables
  double exposure_phase_ = 0.0;
  double render_time_s_ = 0.0, effects_time_s_ = 0.0;
};

/// About the bytes a sequence of `options` takes on disk: its frames' colour, depth and mask PNGs
/// (0.9 MB a VGA frame of the photo-textured scenes, a 45 s sequence 1.1-1.2 GB; scaled by the pixel
/// count) with a quarter of margin.
std::uintmax_t expectedSequenceBytes(const SimOptions& options);

/// Throws InputError naming out_dir when the file system holding it (out_dir or its nearest existing
/// parent) has fewer than `bytes` available: a sequence that cannot fit fails before its first frame,
/// not part-way with the disk full for every other job.
void requireFreeSpace(const std::string& out_dir, std::uintmax_t bytes);

/// Generates the whole sequence into out_dir (created if missing) in the DATA_FORMAT.md layout,
/// plus stats.txt, scene.ply and imu_biases.txt; progress every `progress_every` frames.
/// Throws InputError when out_dir cannot be written or its file system lacks the space
/// expectedSequenceBytes says.
SequenceStats writeSequence(const SimOptions& options, const std::string& out_dir,
                            int progress_every = 100);
SequenceStats writeSequence(Simulator& sim, const std::string& out_dir, int progress_every = 100);

}  // namespace ltlo::sim
