#pragma once
/// Sensor profiles of the simulator (issue 28, "real sensors"): the faults of a real RGB-D-inertial
/// sensor, each behind its own switch so that one can be turned on at a time. Profiles are YAML files
/// (config_yaml/sensor_<name>.yaml, keys Sensor.*, every key optional); the default profile is the
/// ideal sensor of issue 3 (every switch off), and then every output file is byte for byte what the
/// simulator wrote before profiles existed.
///
/// What a profile changes (see Examples/simulate/README.md and each key's comment in the YAML files):
///   - lens: colour, depth and masks are delivered in the distorted raw pixel grid of CameraModel;
///   - camera-IMU time offset, Kalibr's convention t_imu = t_cam + offset: camera stamps are the true
///     instants, an IMU sample taken at true time t is stamped t + offset;
///   - extrinsic error: calib.yaml's IMU.T_b_c1 is the true T_b_c times a small error T_c_ce;
///   - IMU scale factor and axis misalignment: measured = M (true) + bias + noise;
///   - accelerometer and gyroscope on their own clocks and rates (half rows in imu.txt);
///   - timestamp jitter of camera and IMU stamps;
///   - auto-exposure steps and slow drift of the colour gain;
///   - dropped frames (bursts missing from the frame lists; the IMU runs on);
///   - rolling shutter (each row exposed at its own time).
/// The ground truth stays exact (groundtruth.txt: the true pose of the instant each written image was
/// taken, under its stamp); what the faults were is written to sensor_truth.yaml (evaluation only).
#include <cstdint>
#include <string>
#include <vector>

#include "ltlo/core/camera_model.h"
#include "ltlo/core/lie.h"

namespace ltlo {
class SettingsFile;
}

namespace ltlo::sim {

/// The lenses of --lens and of the shipped profiles (coefficients and their sources in
/// sensor_profile.cc): no lens, the mild D435-like radial-tangential lens, a stronger barrel one
/// (~24 px at the corners of VGA), the Azure-Kinect-like 8-coefficient rational lens and a
/// Kannala-Brandt (equidistant) lens.
enum class LensPreset { kNone, kRadTan, kRadTanStrong, kRational, kKannalaBrandt };

/// "none", "radtan", "radtan-strong", "rational", "kb"; false when unknown.
bool parseLensPreset(const std::string& text, LensPreset* preset);
/// The preset's distortion (model kPinhole for kNone).
LensDistortion lensPreset(LensPreset preset);

struct SensorProfile {
  std::string name = "ideal";  ///< Sensor.Name (stats.txt, sensor_truth.yaml)

  // Lens (Sensor.Distortion.*).
  bool lens_enable = false;  ///< Sensor.Distortion.Enable
  /// Sensor.Distortion.Model ("radtan", "rational", "kb") and .K1 .. .K6, .P1, .P2 (coefficients absent
  /// from the file are the model's preset values).
  LensDistortion lens;

  // Camera-IMU time offset (Sensor.TimeOffset.*).
  bool time_offset_enable = false;    ///< Sensor.TimeOffset.Enable
  double time_offset_s = 0.0;         ///< Sensor.TimeOffset.Value (s), t_imu = t_cam + offset, [-0.2, 0.2]
  bool time_offset_in_calib = false;  ///< Sensor.TimeOffset.WriteToCalib: IMU.TimeOffset = the true value (else 0)

  // Camera-IMU extrinsic error (Sensor.Extrinsic.*): fixed magnitudes, random directions per seed.
  bool extrinsic_enable = false;         ///< Sensor.Extrinsic.Enable
  double extrinsic_translation_m = 0.0;  ///< Sensor.Extrinsic.TranslationError (m) [0, 0.1]
  double extrinsic_rotation_deg = 0.0;   ///< Sensor.Extrinsic.RotationError (deg) [0, 5]

  // IMU scale factors and axis misalignment (Sensor.ImuIntrinsics.*): each scale error and each
  // misalignment angle is +-value * U(0.6, 1.4), signs and factors random per seed.
  bool imu_intrinsics_enable = false;  ///< Sensor.ImuIntrinsics.Enable
  double gyro_scale_error = 0.0;       ///< Sensor.ImuIntrinsics.GyroScale (fraction) [0, 0.05]
  double gyro_misalignment_rad = 0.0;  ///< Sensor.ImuIntrinsics.GyroMisalignment (rad) [0, 0.05]
  double acc_scale_error = 0.0;        ///< Sensor.ImuIntrinsics.AccScale (fraction) [0, 0.05]
  double acc_misalignment_rad = 0.0;   ///< Sensor.ImuIntrinsics.AccMisalignment (rad) [0, 0.05]

  // Accelerometer and gyroscope on their own clocks (Sensor.ImuClocks.*); off: one clock at IMU.Frequency.
  bool imu_clocks_enable = false;  ///< Sensor.ImuClocks.Enable
  double gyro_rate_hz = 200.0;     ///< Sensor.ImuClocks.GyroRate (Hz) [10, 4000]
  double acc_rate_hz = 250.0;      ///< Sensor.ImuClocks.AccRate (Hz) [10, 4000]
  /// Sensor.ImuClocks.MergedRows: full rows at the gyro stamps (accelerometer linearly interpolated
  /// between its neighbouring stamps, as drivers unite them) instead of half rows.
  bool merged_rows = false;

  // Timestamp jitter (Sensor.Jitter.*): Gaussian, clipped at 3 sigma.
  bool jitter_enable = false;    ///< Sensor.Jitter.Enable
  double camera_jitter_s = 0.0;  ///< Sensor.Jitter.Camera (s, std) [0, 0.005]
  double imu_jitter_s = 0.0;     ///< Sensor.Jitter.Imu (s, std) [0, 0.005]

  // Auto-exposure of the colour image (Sensor.Exposure.*): gain steps and a slow drift.
  bool exposure_enable = false;          ///< Sensor.Exposure.Enable
  double exposure_steps_per_min = 0.0;   ///< Sensor.Exposure.StepsPerMinute (Poisson) [0, 60]
  double exposure_step_min = 0.15;       ///< Sensor.Exposure.StepMin: smallest |gain change| (fraction) [0, 1]
  double exposure_step_max = 0.30;       ///< Sensor.Exposure.StepMax: largest (fraction) [StepMin, 1]
  double exposure_ramp_s = 0.3;          ///< Sensor.Exposure.Ramp: duration of a step (s) [0, 5]
  double exposure_drift = 0.0;           ///< Sensor.Exposure.DriftAmplitude (fraction) [0, 0.5]
  double exposure_drift_period_s = 40.0; ///< Sensor.Exposure.DriftPeriod (s) [1, 3600]

  // Dropped frames (Sensor.Drops.*).
  bool drops_enable = false;  ///< Sensor.Drops.Enable
  double drop_rate = 0.0;     ///< Sensor.Drops.Rate: expected share of frames missing [0, 0.5]
  int drop_max_burst = 1;     ///< Sensor.Drops.MaxBurst: bursts of 1 .. MaxBurst frames [1, 30]

  // Rolling shutter (Sensor.RollingShutter.*).
  bool rolling_shutter_enable = false;  ///< Sensor.RollingShutter.Enable
  double readout_s = 0.025;             ///< Sensor.RollingShutter.Readout: first to last row (s) [0, 0.1]
  int rolling_shutter_bands = 8;        ///< Sensor.RollingShutter.Bands: rows rendered at one time [2, 480]

  /// Every switch off: the simulator takes exactly the code paths of the ideal sensor.
  bool isIdeal() const;
  /// One line for stats.txt and the log: "realsense: lens radtan k1=..., time offset 0.006 s, ...".
  std::string describe() const;

  /// Reads a profile (every key optional: defaults are the ideal sensor's switches and the values
  /// above); throws ConfigError naming file, key, range and value.
  static SensorProfile load(const SettingsFile& file);
};

/// Auto-exposure step: the gain multiplies by `ratio` over [t_s, t_s + ramp] (smoothstep ramp).
struct ExposureStep {
  double t_s = 0.0;
  double ratio = 1.0;
};

/// The faults of one sequence as drawn from the profile and the seed (the "true sensor").
struct SensorTruth {
  LensDistortion lens;             ///< kPinhole when the lens is off
  double time_offset_s = 0.0;      ///< t_imu = t_cam + offset (0 when off)
  SE3 T_b_c;                       ///< true camera pose in the body frame
  SE3 T_b_c_calib;                 ///< what calib.yaml says (T_b_c * T_c_ce)
  Mat3 M_gyro = Mat3::Identity();  ///< measured rate = M_gyro omega_b + b_g + noise
  Mat3 M_acc = Mat3::Identity();   ///< measured force = M_acc f_b + b_a + noise
  double gyro_rate_hz = 0.0, acc_rate_hz = 0.0;  ///< both the IMU rate without separate clocks
  double acc_phase_s = 0.0;        ///< first accelerometer stamp (the gyroscope's is 0)
  std::vector<ExposureStep> exposure_steps;
  double exposure_drift = 0.0, exposure_drift_period_s = 1.0, exposure_drift_phase_rad = 0.0;
  double exposure_ramp_s = 0.0;
  std::vector<uint8_t> dropped;         ///< per frame of the camera clock: 1 = not delivered
  std::vector<double> camera_stamp_s;   ///< per frame: the stamp written (true instant + jitter)

  /// Colour gain of the auto-exposure at true time t_s (1 without it).
  double exposureGain(double t_s) const;
};

/// Draws the faults for `seed` from their own random streams (the ideal sensor's draws are untouched).
/// `frame_times_s`: true instants of the camera clock's frames.
SensorTruth drawSensorTruth(const SensorProfile& profile, uint64_t seed, const SE3& T_b_c,
                            double imu_rate_hz, const std::vector<double>& frame_times_s);

/// Frames as written, for sensor_truth.yaml.
struct WrittenFrame {
  int index = 0;        ///< frame of the camera clock
  double stamp_s = 0.0; ///< as in rgb.txt
  double true_s = 0.0;  ///< instant the image was taken (centre row with a rolling shutter)
  double gain = 1.0;    ///< colour gain applied (exposure jitter times auto-exposure)
};

/// Writes SEQ/sensor_truth.yaml (OpenCV FileStorage YAML, keys Truth.*; evaluation only).
void writeSensorTruth(const std::string& path, const SensorProfile& profile, const SensorTruth& truth,
                      const std::vector<WrittenFrame>& frames, const std::vector<double>& frame_times_s);

}  // namespace ltlo::sim
