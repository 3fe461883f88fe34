#include "ltlo/sim/imu_simulator.h"

#include <cmath>
#include <random>

namespace ltlo::sim {

std::vector<ImuSample> simulateImu(const RobotTrajectory& trajectory, const SimOptions& options) {
  const Vec3 g_w(0.0, 0.0, -kGravityMps2);
  const double rate_hz = options.imu_rate_hz;
  const int num_samples = static_cast<int>(std::floor(options.duration_s * rate_hz + 1e-9)) + 1;
  std::mt19937_64 rng(options.seed * 104729 + 3);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto gaussian3 = [&]() { return Vec3(normal(rng), normal(rng), normal(rng)); };

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
    const double t_s = k / rate_hz;
    const RobotState s = trajectory.state(t_s);
    ImuSample sample;
    sample.t_s = t_s;
    sample.gyro_rad_s = s.omega_b;
    sample.acc_mps2 = s.T_w_b.rotationMatrix().transpose() * (s.a_w_b - g_w);
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
