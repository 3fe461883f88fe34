#include "ltlo/sim/sensor_profile.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <random>
#include <sstream>

#include "ltlo/core/errors.h"
#include "ltlo/core/settings_file.h"

namespace ltlo::sim {
namespace {

// Each fault draws from its own stream, so turning one fault on never changes another's draws (and
// none of them touches the ideal sensor's streams).
enum class Stream : uint64_t { kExtrinsic = 1, kImuIntrinsics, kClocks, kJitter, kExposure, kDrops };

std::mt19937_64 faultRng(uint64_t seed, Stream stream) {
  return std::mt19937_64(seed * 0x9E3779B97F4A7C15ULL + 28 * 1000 + static_cast<uint64_t>(stream));
}

double roundToMicroseconds(double t_s) { return std::round(t_s * 1e6) * 1e-6; }

double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

Vec3 randomUnitVector(std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Vec3 v;
  do {
    v = Vec3(normal(rng), normal(rng), normal(rng));
  } while (v.norm() < 1e-6);
  return v.normalized();
}

// (I + diag(s)) (I + T): scale errors s_i and a lower-triangular T of three small angles (y tilted
// towards x, z towards x and y: non-orthogonal axes against the frame of the x axis and the x-y plane).
// Each element is +-magnitude * U(0.6, 1.4) with a random sign.
Mat3 scaleMisalignment(double scale_error, double misalignment_rad, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> factor(0.6, 1.4);
  std::bernoulli_distribution negative(0.5);
  auto draw = [&](double magnitude) { return (negative(rng) ? -1.0 : 1.0) * magnitude * factor(rng); };
  Mat3 S = Mat3::Identity();
  for (int i = 0; i < 3; ++i) S(i, i) += draw(scale_error);
  Mat3 T = Mat3::Identity();
  T(1, 0) = draw(misalignment_rad);
  T(2, 0) = draw(misalignment_rad);
  T(2, 1) = draw(misalignment_rad);
  return S * T;
}

const char* modelKey(LensModel model) {
  switch (model) {
    case LensModel::kRadTan: return "radtan";
    case LensModel::kRational: return "rational";
    case LensModel::kKannalaBrandt: return "kb";
    case LensModel::kPinhole: break;
  }
  return "none";
}

std::string matrixYaml(const Eigen::MatrixXd& M) {
  std::ostringstream out;
  out << std::setprecision(17) << "!!opencv-matrix\n   rows: " << M.rows() << "\n   cols: " << M.cols()
      << "\n   dt: d\n   data: [ ";
  for (int r = 0; r < M.rows(); ++r)
    for (int c = 0; c < M.cols(); ++c)
      out << M(r, c) << (r == M.rows() - 1 && c == M.cols() - 1 ? " ]\n" : ", ");
  return out.str();
}

template <typename T, typename F>
std::string flowList(const std::vector<T>& values, F format) {
  std::string text = "[";
  for (size_t i = 0; i < values.size(); ++i) text += (i ? ", " : " ") + format(values[i]);
  return text + (values.empty() ? "]" : " ]");
}

std::string fixed(double value, int decimals) {
  char buffer[48];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

}  // namespace

bool parseLensPreset(const std::string& text, LensPreset* preset) {
  const struct {
    const char* name;
    LensPreset value;
  } kNames[] = {{"none", LensPreset::kNone},
                {"radtan", LensPreset::kRadTan},
                {"radtan-strong", LensPreset::kRadTanStrong},
                {"rational", LensPreset::kRational},
                {"kb", LensPreset::kKannalaBrandt}};
  for (const auto& entry : kNames) {
    if (text == entry.name) {
      *preset = entry.value;
      return true;
    }
  }
  return false;
}

LensDistortion lensPreset(LensPreset preset) {
  LensDistortion lens;
  switch (preset) {
    case LensPreset::kNone: break;
    case LensPreset::kRadTan:
      // D435-like: librealsense reports all-zero Brown-Conrady coefficients for the D415/D435 colour
      // stream, yet checkerboard calibrations of the same lens find small ones (librealsense issue
      // #7550). A mild lens: 2.8 px at the corners of VGA (fx = 525), 1.7 px at the side edges.
      lens.model = LensModel::kRadTan;
      lens.k1 = 0.015;
      lens.k2 = -0.005;
      lens.p1 = 4.0e-4;
      lens.p2 = -3.0e-4;
      break;
    case LensPreset::kRadTanStrong:
      // A stronger barrel lens (an uncalibrated wide-angle board camera): 24 px at the corners of VGA.
      lens.model = LensModel::kRadTan;
      lens.k1 = -0.095;
      lens.k2 = 0.01;
      lens.p1 = 4.0e-4;
      lens.p2 = -3.0e-4;
      break;
    case LensPreset::kRational:
      // Azure Kinect colour camera, one device's factory calibration (Azure-Kinect-Sensor-SDK issue
      // #1488, camera PV0, rounded; the SDK stores p2 before p1). Made for its 90 x 59 deg view; over our
      // 62 x 49 deg VGA view it moves the corners by 13 px.
      lens.model = LensModel::kRational;
      lens.k1 = 0.4039;
      lens.k2 = -2.6029;
      lens.k3 = 1.5119;
      lens.k4 = 0.2843;
      lens.k5 = -2.4207;
      lens.k6 = 1.4354;
      lens.p1 = 8.9e-4;
      lens.p2 = -4.2e-5;
      break;
    case LensPreset::kKannalaBrandt:
      // No particular device: an equidistant-model lens a little wider than the pinhole (a pinhole
      // is k1 = 1/3, k2 = 2/15 in this model), 20 px of barrel at the corners of VGA; it exercises the
      // Kannala-Brandt path.
      lens.model = LensModel::kKannalaBrandt;
      lens.k1 = 0.26;
      lens.k2 = 0.05;
      break;
  }
  return lens;
}

bool SensorProfile::isIdeal() const {
  return !lens_enable && !time_offset_enable && !extrinsic_enable && !imu_intrinsics_enable &&
         !imu_clocks_enable && !jitter_enable && !exposure_enable && !drops_enable &&
         !rolling_shutter_enable;
}

std::string SensorProfile::describe() const {
  std::ostringstream text;
  text << name << ":";
  if (isIdeal()) return text.str() + " ideal sensor (no faults)";
  const char* separator = " ";
  auto item = [&]() -> std::ostream& {
    text << separator;
    separator = "; ";
    return text;
  };
  if (lens_enable) item() << "lens " << lens.describe();
  if (time_offset_enable)
    item() << "time offset " << time_offset_s << " s (t_imu = t_cam + offset; calib.yaml "
           << (time_offset_in_calib ? "has it" : "says 0") << ")";
  if (extrinsic_enable)
    item() << "extrinsic error " << 1e3 * extrinsic_translation_m << " mm " << extrinsic_rotation_deg << " deg";
  if (imu_intrinsics_enable)
    item() << "IMU scale/misalignment gyro " << 100 * gyro_scale_error << " % " << 1e3 * gyro_misalignment_rad
           << " mrad, accel " << 100 * acc_scale_error << " % " << 1e3 * acc_misalignment_rad << " mrad";
  if (imu_clocks_enable)
    item() << "gyro " << gyro_rate_hz << " Hz, accel " << acc_rate_hz << " Hz on own clocks ("
           << (merged_rows ? "merged rows" : "half rows") << ")";
  if (jitter_enable) item() << "stamp jitter camera " << 1e3 * camera_jitter_s << " ms, IMU " << 1e3 * imu_jitter_s << " ms";
  if (exposure_enable)
    item() << "auto-exposure " << exposure_steps_per_min << " steps/min of " << 100 * exposure_step_min << "-"
           << 100 * exposure_step_max << " % (ramp " << exposure_ramp_s << " s), drift " << 100 * exposure_drift
           << " % over " << exposure_drift_period_s << " s";
  if (drops_enable) item() << "dropped frames " << 100 * drop_rate << " % in bursts of 1-" << drop_max_burst;
  if (rolling_shutter_enable)
    item() << "rolling shutter " << 1e3 * readout_s << " ms readout, " << rolling_shutter_bands << " bands";
  return text.str();
}

SensorProfile SensorProfile::load(const SettingsFile& file) {
  SensorProfile p;
  p.name = file.getString("Sensor.Name", p.name);

  p.lens_enable = file.getBool("Sensor.Distortion.Enable", false);
  const std::string model = file.getString("Sensor.Distortion.Model", "radtan");
  LensPreset preset = LensPreset::kRadTan;
  if (model == "rational") {
    preset = LensPreset::kRational;
  } else if (model == "kb") {
    preset = LensPreset::kKannalaBrandt;
  } else if (model != "radtan") {
    file.fail("Sensor.Distortion.Model", "\"" + model + "\"", "\"radtan\", \"rational\" or \"kb\"");
  }
  p.lens = lensPreset(preset);
  auto coefficient = [&](const char* key, double* value) {
    *value = file.getDouble(std::string("Sensor.Distortion.") + key, *value, -100.0, 100.0);
  };
  coefficient("K1", &p.lens.k1);
  coefficient("K2", &p.lens.k2);
  if (preset != LensPreset::kKannalaBrandt) {
    coefficient("P1", &p.lens.p1);
    coefficient("P2", &p.lens.p2);
  }
  coefficient("K3", &p.lens.k3);
  if (preset != LensPreset::kRadTan) coefficient("K4", &p.lens.k4);
  if (preset == LensPreset::kRational) {
    coefficient("K5", &p.lens.k5);
    coefficient("K6", &p.lens.k6);
  }

  p.time_offset_enable = file.getBool("Sensor.TimeOffset.Enable", false);
  p.time_offset_s = file.getDouble("Sensor.TimeOffset.Value", p.time_offset_s, -0.2, 0.2);
  p.time_offset_in_calib = file.getBool("Sensor.TimeOffset.WriteToCalib", false);

  p.extrinsic_enable = file.getBool("Sensor.Extrinsic.Enable", false);
  p.extrinsic_translation_m = file.getDouble("Sensor.Extrinsic.TranslationError", p.extrinsic_translation_m, 0.0, 0.1);
  p.extrinsic_rotation_deg = file.getDouble("Sensor.Extrinsic.RotationError", p.extrinsic_rotation_deg, 0.0, 5.0);

  p.imu_intrinsics_enable = file.getBool("Sensor.ImuIntrinsics.Enable", false);
  p.gyro_scale_error = file.getDouble("Sensor.ImuIntrinsics.GyroScale", p.gyro_scale_error, 0.0, 0.05);
  p.gyro_misalignment_rad =
      file.getDouble("Sensor.ImuIntrinsics.GyroMisalignment", p.gyro_misalignment_rad, 0.0, 0.05);
  p.acc_scale_error = file.getDouble("Sensor.ImuIntrinsics.AccScale", p.acc_scale_error, 0.0, 0.05);
  p.acc_misalignment_rad = file.getDouble("Sensor.ImuIntrinsics.AccMisalignment", p.acc_misalignment_rad, 0.0, 0.05);

  p.imu_clocks_enable = file.getBool("Sensor.ImuClocks.Enable", false);
  p.gyro_rate_hz = file.getDouble("Sensor.ImuClocks.GyroRate", p.gyro_rate_hz, 10.0, 4000.0);
  p.acc_rate_hz = file.getDouble("Sensor.ImuClocks.AccRate", p.acc_rate_hz, 10.0, 4000.0);
  p.merged_rows = file.getBool("Sensor.ImuClocks.MergedRows", false);

  p.jitter_enable = file.getBool("Sensor.Jitter.Enable", false);
  p.camera_jitter_s = file.getDouble("Sensor.Jitter.Camera", p.camera_jitter_s, 0.0, 0.005);
  p.imu_jitter_s = file.getDouble("Sensor.Jitter.Imu", p.imu_jitter_s, 0.0, 0.005);

  p.exposure_enable = file.getBool("Sensor.Exposure.Enable", false);
  p.exposure_steps_per_min = file.getDouble("Sensor.Exposure.StepsPerMinute", p.exposure_steps_per_min, 0.0, 60.0);
  p.exposure_step_min = file.getDouble("Sensor.Exposure.StepMin", p.exposure_step_min, 0.0, 1.0);
  p.exposure_step_max = file.getDouble("Sensor.Exposure.StepMax", p.exposure_step_max, 0.0, 1.0);
  if (p.exposure_step_max < p.exposure_step_min)
    file.fail("Sensor.Exposure.StepMax", std::to_string(p.exposure_step_max), "a value >= Sensor.Exposure.StepMin");
  p.exposure_ramp_s = file.getDouble("Sensor.Exposure.Ramp", p.exposure_ramp_s, 0.0, 5.0);
  p.exposure_drift = file.getDouble("Sensor.Exposure.DriftAmplitude", p.exposure_drift, 0.0, 0.5);
  p.exposure_drift_period_s = file.getDouble("Sensor.Exposure.DriftPeriod", p.exposure_drift_period_s, 1.0, 3600.0);

  p.drops_enable = file.getBool("Sensor.Drops.Enable", false);
  p.drop_rate = file.getDouble("Sensor.Drops.Rate", p.drop_rate, 0.0, 0.5);
  p.drop_max_burst = file.getInt("Sensor.Drops.MaxBurst", p.drop_max_burst, 1, 30);

  p.rolling_shutter_enable = file.getBool("Sensor.RollingShutter.Enable", false);
  p.readout_s = file.getDouble("Sensor.RollingShutter.Readout", p.readout_s, 0.0, 0.1);
  p.rolling_shutter_bands = file.getInt("Sensor.RollingShutter.Bands", p.rolling_shutter_bands, 2, 480);
  file.warnUnreadKeys();
  return p;
}

double SensorTruth::exposureGain(double t_s) const {
  double gain = 1.0;
  for (const ExposureStep& step : exposure_steps) {
    if (t_s < step.t_s) break;
    const double progress = exposure_ramp_s > 0.0 ? smoothstep((t_s - step.t_s) / exposure_ramp_s) : 1.0;
    gain *= 1.0 + (step.ratio - 1.0) * progress;
  }
  if (exposure_drift > 0.0)
    gain *= 1.0 + exposure_drift * std::sin(2.0 * M_PI * t_s / exposure_drift_period_s + exposure_drift_phase_rad);
  return gain;
}

SensorTruth drawSensorTruth(const SensorProfile& profile, uint64_t seed, const SE3& T_b_c,
                            double imu_rate_hz, const std::vector<double>& frame_times_s) {
  SensorTruth truth;
  if (profile.lens_enable) truth.lens = profile.lens;
  if (profile.time_offset_enable) truth.time_offset_s = profile.time_offset_s;
  truth.T_b_c = T_b_c;
  truth.T_b_c_calib = T_b_c;
  if (profile.extrinsic_enable) {
    std::mt19937_64 rng = faultRng(seed, Stream::kExtrinsic);
    const Vec3 axis = randomUnitVector(rng);
    const Vec3 direction = randomUnitVector(rng);
    // Error in the camera frame: p_c(calib) = T_c_ce p_ce, so the calibration's camera is the true one
    // moved by extrinsic_translation_m and turned by extrinsic_rotation_deg.
    const SE3 T_c_ce(so3ExpQuat(profile.extrinsic_rotation_deg * M_PI / 180.0 * axis),
                     profile.extrinsic_translation_m * direction);
    truth.T_b_c_calib = T_b_c * T_c_ce;
  }
  if (profile.imu_intrinsics_enable) {
    std::mt19937_64 rng = faultRng(seed, Stream::kImuIntrinsics);
    truth.M_gyro = scaleMisalignment(profile.gyro_scale_error, profile.gyro_misalignment_rad, rng);
    truth.M_acc = scaleMisalignment(profile.acc_scale_error, profile.acc_misalignment_rad, rng);
  }
  truth.gyro_rate_hz = truth.acc_rate_hz = imu_rate_hz;
  if (profile.imu_clocks_enable) {
    std::mt19937_64 rng = faultRng(seed, Stream::kClocks);
    truth.gyro_rate_hz = profile.gyro_rate_hz;
    truth.acc_rate_hz = profile.acc_rate_hz;
    // Free-running clocks: the accelerometer's first sample falls anywhere in its period.
    truth.acc_phase_s = roundToMicroseconds(std::uniform_real_distribution<double>(0.0, 1.0)(rng) / truth.acc_rate_hz);
  }

  const size_t num_frames = frame_times_s.size();
  truth.camera_stamp_s = frame_times_s;
  if (profile.jitter_enable && profile.camera_jitter_s > 0.0) {
    std::mt19937_64 rng = faultRng(seed, Stream::kJitter);
    std::normal_distribution<double> normal(0.0, 1.0);
    double previous = -1.0;
    for (size_t i = 0; i < num_frames; ++i) {
      const double jitter = profile.camera_jitter_s * std::clamp(normal(rng), -3.0, 3.0);
      // Stamps are microseconds in the file names; a driver's stamps never go back or repeat.
      const double stamp = roundToMicroseconds(std::max(0.0, frame_times_s[i] + jitter));
      truth.camera_stamp_s[i] = std::max(stamp, roundToMicroseconds(previous + 1e-6));
      previous = truth.camera_stamp_s[i];
    }
  }

  if (profile.exposure_enable) {
    std::mt19937_64 rng = faultRng(seed, Stream::kExposure);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    truth.exposure_ramp_s = profile.exposure_ramp_s;
    truth.exposure_drift = profile.exposure_drift;
    truth.exposure_drift_period_s = profile.exposure_drift_period_s;
    truth.exposure_drift_phase_rad = 2.0 * M_PI * unit(rng);
    const double end_s = num_frames > 0 ? frame_times_s.back() : 0.0;
    if (profile.exposure_steps_per_min > 0.0) {
      std::exponential_distribution<double> gap(profile.exposure_steps_per_min / 60.0);
      double level = 1.0;
      for (double t = gap(rng); t < end_s; t += gap(rng)) {
        const double size = profile.exposure_step_min + (profile.exposure_step_max - profile.exposure_step_min) * unit(rng);
        // Auto-exposure reacts to the scene getting brighter or darker; away from the mean level it
        // is more likely to come back (the gain wanders but stays within a factor of ~2).
        const double p_up = level > 1.1 ? 0.2 : level < 0.9 ? 0.8 : 0.5;
        const double ratio = unit(rng) < p_up ? 1.0 + size : 1.0 / (1.0 + size);
        level *= ratio;
        truth.exposure_steps.push_back({t, ratio});
      }
    }
  }

  truth.dropped.assign(num_frames, 0);
  if (profile.drops_enable && profile.drop_rate > 0.0) {
    std::mt19937_64 rng = faultRng(seed, Stream::kDrops);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::uniform_int_distribution<int> burst(1, profile.drop_max_burst);
    // A burst starts after a delivered frame with probability p: mean burst B = (1 + MaxBurst) / 2 and
    // share = B / (B + 1 / p), so p = share / (B (1 - share)).
    const double mean_burst = 0.5 * (1.0 + profile.drop_max_burst);
    const double p_start = std::min(1.0, profile.drop_rate / (mean_burst * (1.0 - profile.drop_rate)));
    for (size_t i = 1; i < num_frames;) {  // the first frame is always delivered
      if (unit(rng) < p_start) {
        const int length = burst(rng);
        for (int k = 0; k < length && i < num_frames; ++k) truth.dropped[i++] = 1;
      }
      ++i;  // the frame after a burst (or a kept frame) is delivered
    }
  }
  return truth;
}

void writeSensorTruth(const std::string& path, const SensorProfile& profile, const SensorTruth& truth,
                      const std::vector<WrittenFrame>& frames, const std::vector<double>& frame_times_s) {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  out << std::setprecision(17);
  out << "%YAML:1.0\n---\n"
      << "# The true sensor of this sequence (simulate --sensor): for evaluation only, never an input of the\n"
      << "# estimator. Frames of the camera clock are numbered from 0 at i / fps; Examples/simulate/README.md.\n";
  out << "Truth.Profile: \"" << profile.name << "\"\n";
  out << "Truth.Description: \"" << profile.describe() << "\"\n";
  const LensDistortion& lens = truth.lens;
  out << "# Lens of the raw images (colour, depth and masks): CameraModel's distortion of the normalised plane.\n";
  out << "Truth.Lens.Model: \"" << modelKey(lens.model) << "\"\n";
  for (const auto& [key, value] : {std::pair<const char*, double>{"k1", lens.k1}, {"k2", lens.k2}, {"k3", lens.k3},
                                   {"k4", lens.k4}, {"k5", lens.k5}, {"k6", lens.k6}, {"p1", lens.p1}, {"p2", lens.p2}})
    out << "Truth.Lens." << key << ": " << value << "\n";
  out << "# Camera-IMU time offset (s), t_imu = t_cam + offset; whether calib.yaml's IMU.TimeOffset says it.\n";
  out << "Truth.TimeOffset: " << truth.time_offset_s << "\n";
  out << "Truth.TimeOffsetInCalib: " << (profile.time_offset_enable && profile.time_offset_in_calib ? 1 : 0) << "\n";
  out << "# True camera pose in the body frame, and what calib.yaml's IMU.T_b_c1 says.\n";
  out << "Truth.T_b_c: " << matrixYaml(truth.T_b_c.matrix());
  out << "Truth.T_b_c_calib: " << matrixYaml(truth.T_b_c_calib.matrix());
  const SE3 T_c_ce = truth.T_b_c.inverse() * truth.T_b_c_calib;
  out << "Truth.ExtrinsicError.Translation: " << T_c_ce.translation().norm() << "\n";
  out << "Truth.ExtrinsicError.RotationDeg: " << so3Log(T_c_ce.rotationMatrix()).norm() * 180.0 / M_PI << "\n";
  out << "# IMU intrinsics: measured = M * true + bias + noise (body frame).\n";
  out << "Truth.Gyro.M: " << matrixYaml(truth.M_gyro);
  out << "Truth.Acc.M: " << matrixYaml(truth.M_acc);
  out << "# IMU clocks (Hz; the accelerometer's first stamp, s) and rows of imu.txt: full, half or merged.\n";
  out << "Truth.Gyro.Rate: " << truth.gyro_rate_hz << "\nTruth.Acc.Rate: " << truth.acc_rate_hz << "\n";
  out << "Truth.Acc.Phase: " << truth.acc_phase_s << "\n";
  out << "Truth.ImuRows: \"" << (!profile.imu_clocks_enable ? "full" : profile.merged_rows ? "merged" : "half") << "\"\n";
  out << "# Stamp jitter, std (s; Gaussian clipped at 3 sigma).\n";
  out << "Truth.Jitter.Camera: " << (profile.jitter_enable ? profile.camera_jitter_s : 0.0) << "\n";
  out << "Truth.Jitter.Imu: " << (profile.jitter_enable ? profile.imu_jitter_s : 0.0) << "\n";
  out << "# Rolling shutter: row v of H is exposed at t + (v - (H - 1) / 2) * Readout / (H - 1), t = the\n"
      << "# frame's true instant (its centre row); rendered in Bands bands of rows, each at its centre row's time.\n";
  out << "Truth.RollingShutter.Enable: " << (profile.rolling_shutter_enable ? 1 : 0) << "\n";
  out << "Truth.RollingShutter.Readout: " << (profile.rolling_shutter_enable ? profile.readout_s : 0.0) << "\n";
  out << "Truth.RollingShutter.Bands: " << (profile.rolling_shutter_enable ? profile.rolling_shutter_bands : 1) << "\n";
  out << "# Auto-exposure steps: [t_s, gain ratio, ...], each ramped over Ramp seconds; drift amplitude,\n"
      << "# period (s) and phase (rad) of gain *= 1 + A sin(2 pi t / P + phase).\n";
  std::vector<double> steps;
  for (const ExposureStep& step : truth.exposure_steps) steps.insert(steps.end(), {step.t_s, step.ratio});
  out << "Truth.Exposure.Steps: " << flowList(steps, [](double v) { return fixed(v, 6); }) << "\n";
  out << "Truth.Exposure.Ramp: " << truth.exposure_ramp_s << "\n";
  out << "Truth.Exposure.Drift: [ " << truth.exposure_drift << ", " << truth.exposure_drift_period_s << ", "
      << truth.exposure_drift_phase_rad << " ]\n";
  std::vector<int> dropped;
  std::vector<double> dropped_times;
  for (size_t i = 0; i < truth.dropped.size(); ++i) {
    if (!truth.dropped[i]) continue;
    dropped.push_back(static_cast<int>(i));
    dropped_times.push_back(frame_times_s[i]);
  }
  out << "# Frames of the camera clock that were not delivered (index, true instant s).\n";
  out << "Truth.Frames.Total: " << frame_times_s.size() << "\n";
  out << "Truth.Frames.Dropped: " << flowList(dropped, [](int v) { return std::to_string(v); }) << "\n";
  out << "Truth.Frames.DroppedTimes: " << flowList(dropped_times, [](double v) { return fixed(v, 6); }) << "\n";
  out << "# Per written frame (the lines of rgb.txt, in order): clock index, stamp, true instant (s) and the\n"
      << "# colour gain applied (the simulator's exposure jitter times the auto-exposure).\n";
  std::vector<int> index;
  std::vector<double> stamp, true_s, gain;
  for (const WrittenFrame& f : frames) {
    index.push_back(f.index);
    stamp.push_back(f.stamp_s);
    true_s.push_back(f.true_s);
    gain.push_back(f.gain);
  }
  out << "Truth.Frames.Index: " << flowList(index, [](int v) { return std::to_string(v); }) << "\n";
  out << "Truth.Frames.Stamp: " << flowList(stamp, [](double v) { return fixed(v, 6); }) << "\n";
  out << "Truth.Frames.TrueTime: " << flowList(true_s, [](double v) { return fixed(v, 9); }) << "\n";
  out << "Truth.Frames.Gain: " << flowList(gain, [](double v) { return fixed(v, 6); }) << "\n";
  if (!out) throw InputError(path, 0, "write failed");
}

}  // namespace ltlo::sim
