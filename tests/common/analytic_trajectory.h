#pragma once
/// A smooth analytic body trajectory with exact IMU readings, for the preintegration tests.
/// Position and rotation vector are sums of sinusoids; R_w_b(t) = Exp(phi(t)), so the body angular
/// rate is J_r(phi) phi_dot and the specific force is R_w_b^T (p_ddot - g_w).
#include <cmath>
#include <random>
#include <vector>

#include "ltlo/core/lie.h"
#include "ltlo/imu/imu_types.h"
#include "ltlo/imu/inertial_residual.h"

namespace ltlo::imu::test {

class AnalyticTrajectory {
 public:
  Vec3 position(double t) const {
    return Vec3(0.8 * std::sin(1.1 * t), 0.5 * std::cos(0.9 * t) + 0.2 * t,
                0.3 * std::sin(1.7 * t + 0.4));
  }
  Vec3 velocity(double t) const {
    return Vec3(0.8 * 1.1 * std::cos(1.1 * t), -0.5 * 0.9 * std::sin(0.9 * t) + 0.2,
                0.3 * 1.7 * std::cos(1.7 * t + 0.4));
  }
  Vec3 acceleration(double t) const {
    return Vec3(-0.8 * 1.1 * 1.1 * std::sin(1.1 * t), -0.5 * 0.9 * 0.9 * std::cos(0.9 * t),
                -0.3 * 1.7 * 1.7 * std::sin(1.7 * t + 0.4));
  }
  Vec3 rotationVector(double t) const {
    return Vec3(0.3 * std::sin(1.3 * t), 0.2 * std::cos(0.7 * t + 0.5), 0.6 * std::sin(0.9 * t) + 0.4);
  }
  Vec3 rotationVectorRate(double t) const {
    return Vec3(0.3 * 1.3 * std::cos(1.3 * t), -0.2 * 0.7 * std::sin(0.7 * t + 0.5),
                0.6 * 0.9 * std::cos(0.9 * t));
  }
  Mat3 rotation(double t) const { return so3Exp(rotationVector(t)); }

  NavState state(double t) const {
    NavState s;
    s.R_w_b = rotation(t);
    s.p_w_b = position(t);
    s.v_w_b = velocity(t);
    return s;
  }

  /// Exact reading at t (plus bias), body frame.
  ImuSample sample(double t, const ImuBias& bias = ImuBias()) const {
    ImuSample s;
    s.t_s = t;
    s.gyro_rad_s = so3RightJacobian(rotationVector(t)) * rotationVectorRate(t) + bias.b_g;
    s.acc_m_s2 = rotation(t).transpose() * (acceleration(t) - gravityWorld()) + bias.b_a;
    return s;
  }

  /// Readings on the grid t_begin + k / rate_hz, k = 0.. while t <= t_end (+ bias, + white noise of
  /// the discrete per-sample standard deviation when `noise` and `rng` are given).
  std::vector<ImuSample> samples(double t_begin, double t_end, double rate_hz,
                                 const ImuBias& bias = ImuBias(), const ImuNoise* noise = nullptr,
                                 std::mt19937* rng = nullptr) const {
    std::vector<ImuSample> out;
    std::normal_distribution<double> normal(0.0, 1.0);
    const int count = static_cast<int>(std::floor((t_end - t_begin) * rate_hz + 1e-9)) + 1;
    for (int k = 0; k < count; ++k) {
      ImuSample s = sample(t_begin + k / rate_hz, bias);
      if (noise != nullptr && rng != nullptr) {
        const double sigma_g = std::sqrt(noise->gyroCovariance(1.0 / rate_hz)(0, 0));
        const double sigma_a = std::sqrt(noise->accCovariance(1.0 / rate_hz)(0, 0));
        for (int axis = 0; axis < 3; ++axis) s.gyro_rad_s[axis] += sigma_g * normal(*rng);
        for (int axis = 0; axis < 3; ++axis) s.acc_m_s2[axis] += sigma_a * normal(*rng);
      }
      out.push_back(s);
    }
    return out;
  }
};

}  // namespace ltlo::imu::test
