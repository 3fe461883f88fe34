#include "ltlo/sim/sim_options.h"

#include <cmath>

#include "ltlo/core/log.h"
#include "ltlo/core/settings_file.h"

namespace ltlo::sim {

bool parseScenario(const std::string& text, Scenario* scenario) {
  const struct {
    const char* name;
    Scenario value;
  } kNames[] = {{"static", Scenario::kStatic},
                {"stlo", Scenario::kStlo},
                {"mtlo", Scenario::kMtlo},
                {"ltlo", Scenario::kLtlo},
                {"carried", Scenario::kCarried}};
  for (const auto& entry : kNames) {
    if (text == entry.name) {
      *scenario = entry.value;
      return true;
    }
  }
  return false;
}

std::string scenarioName(Scenario scenario) {
  switch (scenario) {
    case Scenario::kStatic:
      return "static";
    case Scenario::kStlo:
      return "stlo";
    case Scenario::kMtlo:
      return "mtlo";
    case Scenario::kLtlo:
      return "ltlo";
    case Scenario::kCarried:
      return "carried";
  }
  return "unknown";
}

PinholeCamera SimOptions::camera() const {
  // Intrinsics are given for 640x480 and scaled with the image (pixel centres kept consistent).
  const double factor = width_px / 640.0;
  const PinholeCamera reference(fx_px, fy_px, cx_px, cy_px, 640, 480);
  const PinholeCamera scaled = reference.scaled(factor);
  return PinholeCamera(scaled.fx(), scaled.fy(), scaled.cx(),
                       (cy_px + 0.5) * height_px / 480.0 - 0.5, width_px, height_px);
}

SE3 SimOptions::T_b_c() {
  // Camera axes in the body frame (x right = -y_b, y down = -z_b, z forward = x_b), then tilted
  // 8 deg down, 1.5 deg yaw and 0.5 deg roll; mounted 0.45 m above and 0.10 m ahead of the IMU.
  Mat3 R_b_c0;
  R_b_c0 << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const double deg = M_PI / 180.0;
  const Mat3 tilt =
      (Eigen::AngleAxisd(8.0 * deg, Vec3::UnitY()) * Eigen::AngleAxisd(1.5 * deg, Vec3::UnitZ()) *
       Eigen::AngleAxisd(0.5 * deg, Vec3::UnitX()))
          .toRotationMatrix();
  return SE3(tilt * R_b_c0, Vec3(0.10, 0.03, 0.45));
}

SensorCalib SimOptions::sensorCalib() const {
  SensorCalib calib;
  calib.camera.camera = camera();
  calib.camera.fps = fps;
  calib.camera.depth_map_factor = depth_map_factor;
  calib.has_imu = true;
  calib.imu.T_b_c = T_b_c();
  calib.imu.noise_gyro = noise_gyro;
  calib.imu.noise_acc = noise_acc;
  calib.imu.gyro_walk = gyro_walk;
  calib.imu.acc_walk = acc_walk;
  calib.imu.rate_hz = imu_rate_hz;
  return calib;
}

namespace {

/// The simulated IMU's rate and noise under the simulator's own keys (Sim.Imu.<name>), so a
/// simulator config never reads like the estimator's settings (IMU.<name>, what the estimator
/// assumes). A config of the old layout (IMU.<name>) still loads, with one warning naming the new
/// key; both in one file is an error.
double readImuKey(const SettingsFile& file, const std::string& name, double default_value, double min,
                  double max) {
  const std::string key = "Sim.Imu." + name;
  const std::string old_key = "IMU." + name;
  if (file.has(old_key)) {
    if (file.has(key))
      file.fail(old_key, file.valueText(old_key), "no value: this file gives " + key + " (the simulator's key) too");
    log::warn(file.path(), ": ", old_key, " in a simulator config is read as ", key, " (rename it)");
    return file.getDouble(old_key, default_value, min, max);
  }
  return file.getDouble(key, default_value, min, max);
}

}  // namespace

SimOptions SimOptions::load(const SettingsFile& file) {
  SimOptions o;
  o.width_px = file.getInt("Camera.width", o.width_px, 16, 4096);
  o.height_px = file.getInt("Camera.height", o.height_px, 16, 4096);
  o.fx_px = file.getDouble("Camera.fx", o.fx_px, 50.0, 5000.0);
  o.fy_px = file.getDouble("Camera.fy", o.fy_px, 50.0, 5000.0);
  o.cx_px = file.getDouble("Camera.cx", o.cx_px, 0.0, 4096.0);
  o.cy_px = file.getDouble("Camera.cy", o.cy_px, 0.0, 4096.0);
  o.fps = file.getDouble("Camera.fps", o.fps, 1.0, 200.0);
  o.depth_map_factor = file.getDouble("DepthMapFactor", o.depth_map_factor, 1.0, 100000.0);
  o.imu_rate_hz = readImuKey(file, "Frequency", o.imu_rate_hz, 10.0, 2000.0);
  o.noise_gyro = readImuKey(file, "NoiseGyro", o.noise_gyro, 0.0, 1.0);
  o.noise_acc = readImuKey(file, "NoiseAcc", o.noise_acc, 0.0, 10.0);
  o.gyro_walk = readImuKey(file, "GyroWalk", o.gyro_walk, 0.0, 1.0);
  o.acc_walk = readImuKey(file, "AccWalk", o.acc_walk, 0.0, 10.0);
  o.gyro_bias_init = file.getDouble("Sim.GyroBiasInit", o.gyro_bias_init, 0.0, 1.0);
  o.acc_bias_init = file.getDouble("Sim.AccBiasInit", o.acc_bias_init, 0.0, 5.0);
  o.depth_min_m = file.getDouble("Depth.MinRange", o.depth_min_m, 0.05, 10.0);
  o.depth_max_m = file.getDouble("Depth.MaxRange", o.depth_max_m, 0.5, 60.0);
  if (o.depth_max_m <= o.depth_min_m)
    file.fail("Depth.MaxRange", std::to_string(o.depth_max_m), "a value above Depth.MinRange");
  o.depth_noise_at_1m_m = file.getDouble("Depth.NoiseAt1m", o.depth_noise_at_1m_m, 0.0, 0.1);
  o.depth_edge_dropout = file.getDouble("Depth.EdgeDropout", o.depth_edge_dropout, 0.0, 1.0);
  o.depth_random_dropout = file.getDouble("Depth.RandomDropout", o.depth_random_dropout, 0.0, 0.5);
  o.rgb_noise_sigma = file.getDouble("Rgb.NoiseSigma", o.rgb_noise_sigma, 0.0, 50.0);
  o.exposure_jitter = file.getDouble("Rgb.ExposureJitter", o.exposure_jitter, 0.0, 0.3);
  o.mean_speed_mps = file.getDouble("Robot.MeanSpeed", o.mean_speed_mps, 0.3, 0.55);
  o.vibration_angle_deg = file.getDouble("Robot.VibrationAngle", o.vibration_angle_deg, 0.0, 1.5);
  o.vibration_height_m = file.getDouble("Robot.VibrationHeight", o.vibration_height_m, 0.0, 0.02);
  o.texture_dir = file.getString("Sim.TextureDir", o.texture_dir);
  o.png_compression = file.getInt("Sim.PngCompression", o.png_compression, 0, 9);
  file.warnUnreadKeys();
  return o;
}

}  // namespace ltlo::sim
