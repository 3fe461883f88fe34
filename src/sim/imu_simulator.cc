#include "ltlo/sim/imu_simulator.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace ltlo::sim {
namespace {

const Vec3 kGravityW(0.0, 0.0, -kGravityMps2);

double roundToMicroseconds(double t_s) { return std::round(t_s * 1e6) * 1e-6; }

// Jittered stamps (microseconds, as written) of nominal ones; never backwards or repeated, as a
// driver's stamps.
class StampJitter {
 public:
  StampJitter(double jitter_s, uint64_t seed) : jitter_s_(jitter_s), rng_(seed) {}
  double operator()(double nominal_s) {
    if (jitter_s_ <= 0.0) return nominal_s;
    const double jitter = jitter_s_ * std::clamp(normal_(rng_), -3.0, 3.0);
    const double stamp = std::max(roundToMicroseconds(std::max(0.0, nominal_s + jitter)),
                                  roundToMicroseconds(previous_s_ + 1e-6));
    previous_s_ = stamp;
    return stamp;
  }

 private:
  double jitter_s_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  double previous_s_ = -1.0;
};

// One sensor (gyroscope or accelerometer) on its own clock: noise, bias walk and its own random stream.
struct Stream {
  std::vector<double> stamp_s, true_s;
  std::vector<Vec3> value, bias;
};

Stream simulateStream(const RobotTrajectory& trajectory, const SimOptions& options, const ImuFaults& faults,
                      bool gyro) {
  const double rate_hz = gyro ? faults.gyro_rate_hz : faults.acc_rate_hz;
  const double phase_s = gyro ? 0.0 : faults.acc_phase_s;
  const double noise = gyro ? options.noise_gyro : options.noise_acc;
  const double walk = gyro ? options.gyro_walk : options.acc_walk;
  const double bias_init = gyro ? options.gyro_bias_init : options.acc_bias_init;
  const Mat3& M = gyro ? faults.M_gyro : faults.M_acc;
  std::mt19937_64 rng(options.seed * 104729 + (gyro ? 11 : 13));
  std::normal_distribution<double> normal(0.0, 1.0);
  auto gaussian3 = [&]() { return Vec3(normal(rng), normal(rng), normal(rng)); };
  StampJitter jitter(faults.jitter_s, options.seed * 104729 + (gyro ? 17 : 19));

  const bool noisy = !options.noise_free;
  Vec3 b = noisy ? Vec3(bias_init * gaussian3()) : Vec3::Zero();
  const double sigma = noise * std::sqrt(rate_hz), sigma_walk = walk / std::sqrt(rate_hz);
  Stream stream;
  for (int k = 0;; ++k) {
    const double nominal_s = phase_s + k / rate_hz;
    if (nominal_s > options.duration_s + 1e-9) break;
    const double t_true = nominal_s - faults.time_offset_s;
    const RobotState s = trajectory.state(t_true);
    Vec3 value = gyro ? s.omega_b : Vec3(s.T_w_b.rotationMatrix().transpose() * (s.a_w_b - kGravityW));
    if (faults.intrinsics) value = M * value;
    stream.bias.push_back(b);
    if (noisy) {
      value += b + sigma * gaussian3();
      b += sigma_walk * gaussian3();
    }
    stream.value.push_back(value);
    stream.true_s.push_back(t_true);
    stream.stamp_s.push_back(jitter(nominal_s));
  }
  return stream;
}

// Both streams in stamp order as half rows; each row's bias pair is the latest of each stream.
std::vector<ImuSample> halfRows(const Stream& gyro, const Stream& acc) {
  std::vector<ImuSample> samples;
  samples.reserve(gyro.stamp_s.size() + acc.stamp_s.size());
  size_t g = 0, a = 0;
  Vec3 bias_gyro = gyro.bias.empty() ? Vec3::Zero() : gyro.bias.front();
  Vec3 bias_acc = acc.bias.empty() ? Vec3::Zero() : acc.bias.front();
  double previous_s = -1.0;
  while (g < gyro.stamp_s.size() || a < acc.stamp_s.size()) {
    const bool take_gyro = a >= acc.stamp_s.size() || (g < gyro.stamp_s.size() && gyro.stamp_s[g] <= acc.stamp_s[a]);
    ImuSample s;
    if (take_gyro) {
      s.t_s = gyro.stamp_s[g];
      s.t_true_s = gyro.true_s[g];
      s.gyro_rad_s = gyro.value[g];
      s.acc_mps2 = Vec3::Constant(std::nan(""));
      s.has_acc = false;
      bias_gyro = gyro.bias[g++];
    } else {
      s.t_s = acc.stamp_s[a];
      s.t_true_s = acc.true_s[a];
      s.acc_mps2 = acc.value[a];
      s.gyro_rad_s = Vec3::Constant(std::nan(""));
      s.has_gyro = false;
      bias_acc = acc.bias[a++];
    }
    // Two sensors may stamp the same microsecond: the later row moves on by one (stamps strictly increase).
    if (previous_s >= 0.0 && roundToMicroseconds(s.t_s) <= roundToMicroseconds(previous_s))
      s.t_s = roundToMicroseconds(previous_s + 1e-6);
    previous_s = s.t_s;
    s.bias_gyro = bias_gyro;
    s.bias_acc = bias_acc;
    samples.push_back(s);
  }
  return samples;
}

// Full rows at the gyroscope's stamps; the accelerometer (and its bias) interpolated on its stamps.
std::vector<ImuSample> mergedRows(const Stream& gyro, const Stream& acc) {
  std::vector<ImuSample> samples;
  size_t a = 0;
  for (size_t g = 0; g < gyro.stamp_s.size(); ++g) {
    const double t = gyro.stamp_s[g];
    while (a + 1 < acc.stamp_s.size() && acc.stamp_s[a + 1] < t) ++a;
    if (a + 1 >= acc.stamp_s.size() || acc.stamp_s[a] > t) continue;  // outside the accelerometer's span
    const double w = (t - acc.stamp_s[a]) / (acc.stamp_s[a + 1] - acc.stamp_s[a]);
    ImuSample s;
    s.t_s = t;
    s.t_true_s = gyro.true_s[g];
    s.gyro_rad_s = gyro.value[g];
    s.bias_gyro = gyro.bias[g];
    s.acc_mps2 = (1.0 - w) * acc.value[a] + w * acc.value[a + 1];
    s.bias_acc = (1.0 - w) * acc.bias[a] + w * acc.bias[a + 1];
    samples.push_back(s);
  }
  return samples;
}

}  // namespace

std::vector<ImuSample> simulateImu(const RobotTrajectory& trajectory, const SimOptions& options,
                                   const ImuFaults& faults) {
  if (faults.separate_clocks) {
    const Stream gyro = simulateStream(trajectory, options, faults, true);
    const Stream acc = simulateStream(trajectory, options, faults, false);
    return faults.merged_rows ? mergedRows(gyro, acc) : halfRows(gyro, acc);
  }
  // One clock: the ideal IMU's random stream and order of draws, so that without faults the samples
  // are exactly those of the ideal sensor.
  const double rate_hz = options.imu_rate_hz;
  const int num_samples = static_cast<int>(std::floor(options.duration_s * rate_hz + 1e-9)) + 1;
  std::mt19937_64 rng(options.seed * 104729 + 3);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto gaussian3 = [&]() { return Vec3(normal(rng), normal(rng), normal(rng)); };
  StampJitter jitter(faults.jitter_s, options.seed * 104729 + 23);

  const bool noisy = !options.noise_free;
  Vec3 b_g = noisy ? Vec3(options.gyro_bias_init * gaussian3()) : Vec3::Zero();
  Vec3 b_a = noisy ? Vec3(options.acc_bias_init * gaussian3()) : Vec3::Zero();
  const double sigma_gyro = options.noise_gyro * std::sqrt(rate_hz);
  const double sigma_acc = options.noise_acc * std::sqrt(rate_hz);
  const double sigma_gyro_walk = options.gyro_walk / std::sqrt(rate_hz);
  const double sigma_acc_walk = options.acc_walk / std::sqrt(rate_hz);

  std::vector<ImuSample> samples;
  samples.reserve(num_samples);
  for (int k = 0; k < num_samples; ++k) {
    const double nominal_s = k / rate_hz;
    const double t_true = nominal_s - faults.time_offset_s;
    const RobotState s = trajectory.state(t_true);
    ImuSample sample;
    sample.t_s = jitter(nominal_s);
    sample.t_true_s = t_true;
    sample.gyro_rad_s = s.omega_b;
    sample.acc_mps2 = s.T_w_b.rotationMatrix().transpose() * (s.a_w_b - kGravityW);
    if (faults.intrinsics) {
      sample.gyro_rad_s = faults.M_gyro * sample.gyro_rad_s;
      sample.acc_mps2 = faults.M_acc * sample.acc_mps2;
    }
    sample.bias_gyro = b_g;
    sample.bias_acc = b_a;
    if (noisy) {
      sample.gyro_rad_s += b_g + sigma_gyro * gaussian3();
      sample.acc_mps2 += b_a + sigma_acc * gaussian3();
      b_g += sigma_gyro_walk * gaussian3();
      b_a += sigma_acc_walk * gaussian3();
    }
    samples.push_back(sample);
  }
  return samples;
}

}  // namespace ltlo::sim
