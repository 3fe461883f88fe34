#pragma once
/// Parameters of the synthetic RGB-D-inertial sequence generator (config_yaml/simulator.yaml).
#include <cstdint>
#include <string>
#include <vector>

#include "ltlo/core/calib.h"
#include "ltlo/sim/robot_trajectory.h"
#include "ltlo/sim/sensor_profile.h"

namespace ltlo {
class SettingsFile;
}

namespace ltlo::sim {

/// Occlusion scenarios of issue 3: share of frames with more than 40 % dynamic pixels.
enum class Scenario {
  kStatic,   ///< no dynamic objects
  kStlo,     ///< short-term large occlusion, ~15-20 % of frames
  kMtlo,     ///< medium-term, ~30 %
  kLtlo,     ///< long-term, 55-75 %, several boxes at once, long stretches
  kCarried,  ///< one box held at a fixed pose relative to the robot for a long stretch
};

/// "static", "stlo", "mtlo", "ltlo", "carried"; returns false when unknown.
bool parseScenario(const std::string& text, Scenario* scenario);
std::string scenarioName(Scenario scenario);

/// How an occluded start's box leaves (simulate --occluded-start).
enum class StartMove {
  kNone,     ///< no occluded start
  kAway,     ///< pushed away: its distance grows while it slides out to a side
  kTowards,  ///< pulled towards the robot to about 0.35 m, then slid out to a side
};

/// A stretch of the sequence where one sensor fails: kBlack gives black colour and no depth (lens
/// covered; forced tracking loss while the IMU runs), kNoDepth keeps colour without depth, kImuGap
/// drops the IMU samples from imu.txt (a dropped driver buffer; imu_biases.txt keeps them).
struct SensorOutage {
  enum class Kind { kBlack, kNoDepth, kImuGap };
  Kind kind = Kind::kBlack;
  double start_s = 0.0;
  double duration_s = 0.0;
  bool covers(double t_s) const { return t_s >= start_s && t_s < start_s + duration_s; }
};

struct SimOptions {
  // Camera (Sim.*)
  int width_px = 640;    ///< Camera.width
  int height_px = 480;   ///< Camera.height
  double fx_px = 525.0;  ///< Camera.fx at 640x480; scaled with the width when it differs
  double fy_px = 525.0;  ///< Camera.fy
  double cx_px = 319.5;  ///< Camera.cx
  double cy_px = 239.5;  ///< Camera.cy
  double fps = 30.0;     ///< Camera.fps (Hz)
  double depth_map_factor = 1000.0;  ///< DepthMapFactor

  // Sequence
  Scenario scenario = Scenario::kStatic;
  uint64_t seed = 1;         ///< drives trajectory details, occlusion schedule and noise
  double duration_s = 10.0;  ///< sequence length (s)
  bool noise_free = false;   ///< no IMU/depth/colour noise, no biases, no holes, no jitter

  // IMU (Sim.Imu.*; written to calib.yaml as IMU.*), low-cost MEMS defaults (datasheet densities inflated as calibration tools do)
  double imu_rate_hz = 200.0;      ///< Sim.Imu.Frequency
  double noise_gyro = 1.0e-3;      ///< Sim.Imu.NoiseGyro (rad/s/sqrt(Hz))
  double noise_acc = 1.0e-2;       ///< Sim.Imu.NoiseAcc (m/s^2/sqrt(Hz))
  double gyro_walk = 1.0e-5;       ///< Sim.Imu.GyroWalk (rad/s^2/sqrt(Hz))
  double acc_walk = 2.0e-4;        ///< Sim.Imu.AccWalk (m/s^3/sqrt(Hz))
  double gyro_bias_init = 2.0e-3;  ///< Sim.GyroBiasInit: std of the initial gyro bias (rad/s)
  double acc_bias_init = 3.0e-2;   ///< Sim.AccBiasInit: std of the initial acc bias (m/s^2)

  // Depth (Depth.*)
  double depth_min_m = 0.25;            ///< Depth.MinRange (m)
  double depth_max_m = 5.5;             ///< Depth.MaxRange (m)
  double depth_noise_at_1m_m = 1.5e-3;  ///< Depth.NoiseAt1m: std (m) at 1 m, grows with z^2
  double depth_edge_dropout = 0.7;      ///< Depth.EdgeDropout: probability of a hole at depth edges
  double depth_random_dropout = 2.0e-3;  ///< Depth.RandomDropout: isolated missing pixels

  // Colour (Rgb.*)
  double rgb_noise_sigma = 2.0;   ///< Rgb.NoiseSigma: intensity noise std (0-255 scale)
  double exposure_jitter = 0.03;  ///< Rgb.ExposureJitter: relative gain amplitude

  // Robot (Robot.*)
  double mean_speed_mps = 0.45;       ///< Robot.MeanSpeed (m/s), stays within 0.3-0.6
  double vibration_angle_deg = 1.2;   ///< Robot.VibrationAngle: amplitude per roll/pitch term
  double vibration_height_m = 0.004;  ///< Robot.VibrationHeight: amplitude per height term

  // Scene (Sim.*)
  std::string texture_dir = "/usr/share/backgrounds";  ///< Sim.TextureDir: photographs
  int png_compression = 1;                             ///< Sim.PngCompression (0-9)

  // Forced sensor failures (command line only; ground truth and masks are unaffected)
  std::vector<SensorOutage> outages;

  // Standstill (command line only, issue 32)
  /// --still START,DURATION: the robot holds its pose (RobotTrajectory's slow-down and speed-up
  /// ramps around it); a still start is --still 0,DURATION.
  std::vector<StillInterval> stills;
  /// --occlusion-at T: a box crosses the view at T (enters from one side, is held 2-4 s, leaves to
  /// the other side), drawn from its own random stream; regular events overlapping it are dropped.
  std::vector<double> occlusion_at_s;

  // Harder worlds (command line only, issue 32); each draws from its own random stream.
  /// --plain-movers: every mover one plain colour; half of the scenario's and --occlusion-at's
  /// events are thin panels instead of boxes, as wide and tall as the box each replaces (the
  /// textured twin's view share: only the texture differs).
  bool plain_movers = false;
  /// --tall-panels (with --plain-movers): the panels are 1.0-1.4 m wide and 1.5-2.0 m tall instead,
  /// up to twice the boxes' size: close to the camera they hide the whole view for seconds (the
  /// stop-44 plain movers, a stress case beyond texture).
  bool tall_panels = false;
  /// --occluded-start away|towards: a box covering 40-80 % of frame 0 leaves by 5 s.
  StartMove occluded_start = StartMove::kNone;
  /// --walkers N: N walking figures over the run (leading the robot or crossing its view).
  int walkers = 0;
  /// --door: door leaves swinging at fixed places of the room.
  bool doors = false;
  /// --three-movers: from t_clear on a leading box, repeated crossing boxes and a carried box.
  bool three_movers = false;

  // Faults of a real sensor (simulate --sensor; default: the ideal sensor). Independent of
  // noise_free, which turns off noise, biases, holes and exposure jitter only.
  SensorProfile sensor;

  /// Camera model at the configured size (fx, fy, cx, cy scaled from 640x480 when width differs).
  PinholeCamera camera() const;
  /// Camera pose in the body (IMU) frame: looks forward, tilted down, offset from the IMU.
  static SE3 T_b_c();
  /// calib.yaml content of the ideal sensor for this configuration (Simulator::calib adds the
  /// profile's faults).
  SensorCalib sensorCalib() const;

  /// Reads the optional keys above from a simulator YAML (defaults when absent); throws
  /// ConfigError naming file, key, range and value.
  static SimOptions load(const SettingsFile& file);
};

}  // namespace ltlo::sim
