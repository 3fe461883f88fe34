#include "ltlo/imu/preintegration.h"

#include <algorithm>
#include <cmath>

#include "ltlo/core/assert.h"
#include "ltlo/core/lie.h"

namespace ltlo::imu {

Preintegrated::Preintegrated(const ImuBias& bias, const ImuNoise& noise)
    : bias_(bias), noise_(noise) {
  reset();
}

void Preintegrated::reset() {
  dt_s_ = 0.0;
  delta_R_.setIdentity();
  delta_v_.setZero();
  delta_p_.setZero();
  covariance_.setZero();
  d_R_d_b_g_.setZero();
  d_v_d_b_g_.setZero();
  d_v_d_b_a_.setZero();
  d_p_d_b_g_.setZero();
  d_p_d_b_a_.setZero();
}

void Preintegrated::integrateStep(const Vec3& gyro_mean_rad_s, const Vec3& acc_mean_m_s2,
                                  double dt_s) {
  LTLO_ASSERT(dt_s >= 0.0, "IMU step dt must be non-negative, got " << dt_s);
  LTLO_ASSERT(gyro_mean_rad_s.allFinite() && acc_mean_m_s2.allFinite(),
              "non-finite IMU reading: gyro " << gyro_mean_rad_s.transpose() << ", acc "
                                              << acc_mean_m_s2.transpose());
  if (dt_s == 0.0) return;
  const Step step{gyro_mean_rad_s, acc_mean_m_s2, dt_s};
  steps_.push_back(step);
  propagate(step);
}

void Preintegrated::integrate(const ImuSample& a, const ImuSample& b) {
  const Vec3 gyro_mean_rad_s = 0.5 * (a.gyro_rad_s + b.gyro_rad_s);
  const Vec3 acc_mean_m_s2 = 0.5 * (a.acc_m_s2 + b.acc_m_s2);
  const double dt_s = b.t_s - a.t_s;
  // Across a gap between samples (the reader integrates across IMU gaps) the step is split into
  // sub-steps of at most kMaxGapStepS with the same mean reading: one step's covariance has rank 6
  // of 9 (its v and p errors come from the same noise), so a frame whose only step spans a 0.5 s
  // gap had a singular covariance (found by the outage soak); sub-steps accumulate the noise as a
  // random walk over the gap. Steps of IMUs at >= 50 Hz are not split.
  constexpr double kMaxGapStepS = 0.02;
  constexpr int kMaxSubSteps = 10000;  // 200 s; a longer gap takes longer sub-steps
  const int sub_steps =
      dt_s > kMaxGapStepS ? static_cast<int>(std::min<double>(std::ceil(dt_s / kMaxGapStepS), kMaxSubSteps)) : 1;
  for (int k = 0; k < sub_steps; ++k) integrateStep(gyro_mean_rad_s, acc_mean_m_s2, dt_s / sub_steps);
}

void Preintegrated::integrate(const std::vector<ImuSample>& samples) {
  for (size_t k = 1; k < samples.size(); ++k) integrate(samples[k - 1], samples[k]);
}

// One midpoint step and the exact linearisation of it (derivation in the header comment):
// with Rh = Exp(w dt/2), Rm = delta_R Rh, Jh = J_r(w dt/2), the error state [phi, v, p] obeys
//   phi' = Exp(w dt)^T phi + J_r(w dt) dt dw
//   v'   = v - Rm a^ Rh^T dt phi - Rm a^ Jh dt^2/2 dw + Rm dt da
//   p'   = p + dt v + dt/2 (the same increment as v)
// where dw, da perturb the bias-corrected readings (dw = -db_g, da = -db_a, or the noise).
void Preintegrated::propagate(const Step& step) {
  const double dt = step.dt_s;
  const Vec3 w = step.gyro_mean_rad_s - bias_.b_g;
  const Vec3 a = step.acc_mean_m_s2 - bias_.b_a;

  const Mat3 R_half = so3Exp(0.5 * dt * w);
  const Mat3 R_step = so3Exp(dt * w);
  const Mat3 R_mid = delta_R_ * R_half;
  const Mat3 J_half = so3RightJacobian(0.5 * dt * w);
  const Mat3 J_step = so3RightJacobian(dt * w);

  const Vec3 acc_rotated = R_mid * a;
  const Mat3 d_dv_d_phi = -R_mid * hat(a) * R_half.transpose() * dt;  // v increment w.r.t. phi
  const Mat3 d_dv_d_w = -R_mid * hat(a) * J_half * (0.5 * dt * dt);   // v increment w.r.t. dw
  const Mat3 d_dv_d_a = R_mid * dt;                                   // v increment w.r.t. da

  // Error-state transition A and noise input B (columns [dw, da]).
  Mat9 A = Mat9::Identity();
  A.block<3, 3>(0, 0) = R_step.transpose();
  A.block<3, 3>(3, 0) = d_dv_d_phi;
  A.block<3, 3>(6, 0) = 0.5 * dt * d_dv_d_phi;
  A.block<3, 3>(6, 3) = Mat3::Identity() * dt;
  Eigen::Matrix<double, 9, 6> B = Eigen::Matrix<double, 9, 6>::Zero();
  B.block<3, 3>(0, 0) = J_step * dt;
  B.block<3, 3>(3, 0) = d_dv_d_w;
  B.block<3, 3>(6, 0) = 0.5 * dt * d_dv_d_w;
  B.block<3, 3>(3, 3) = d_dv_d_a;
  B.block<3, 3>(6, 3) = 0.5 * dt * d_dv_d_a;

  Mat6 noise_cov = Mat6::Zero();
  noise_cov.topLeftCorner<3, 3>() = noise_.gyroCovariance(dt);
  noise_cov.bottomRightCorner<3, 3>() = noise_.accCovariance(dt);
  // Coefficient-wise (lazy) products: faster than Eigen's blocked GEMM at these fixed small sizes.
  const Mat9 A_cov = A.lazyProduct(covariance_);
  const Eigen::Matrix<double, 9, 6> B_noise = B.lazyProduct(noise_cov);
  covariance_ = A_cov.lazyProduct(A.transpose()) + B_noise.lazyProduct(B.transpose());
  covariance_ = 0.5 * (covariance_ + covariance_.transpose());

  // Bias Jacobians (db = -dw / -da), from the old values.
  d_p_d_b_a_ += dt * d_v_d_b_a_ - 0.5 * dt * d_dv_d_a;
  d_p_d_b_g_ += dt * d_v_d_b_g_ + 0.5 * dt * (d_dv_d_phi * d_R_d_b_g_ - d_dv_d_w);
  d_v_d_b_a_ -= d_dv_d_a;
  d_v_d_b_g_ += d_dv_d_phi * d_R_d_b_g_ - d_dv_d_w;
  d_R_d_b_g_ = R_step.transpose() * d_R_d_b_g_ - J_step * dt;

  // Deltas.
  delta_p_ += delta_v_ * dt + 0.5 * dt * dt * acc_rotated;
  delta_v_ += dt * acc_rotated;
  delta_R_ = delta_R_ * R_step;
  // Products of exact rotations drift by ~1e-16 per step: re-project only when it shows.
  if ((delta_R_.transpose() * delta_R_ - Mat3::Identity()).cwiseAbs().maxCoeff() > 1e-12) {
    delta_R_ = normalizeRotation(delta_R_);
  }
  dt_s_ += dt;
}

void Preintegrated::reintegrate(const ImuBias& new_bias) {
  bias_ = new_bias;
  reset();
  for (const Step& step : steps_) propagate(step);
}

void Preintegrated::append(const Preintegrated& next) {
  // Propagation is sequential and uses only this preintegration's bias: continuing it over the
  // raw steps of `next` gives exactly the integration of the union at bias(), at the cost of
  // `next`'s steps alone (the interval held so far is not touched again).
  if (&next == this) {
    const std::vector<Step> own_steps = steps_;  // appending to itself: iterate over a copy
    for (const Step& step : own_steps) {
      steps_.push_back(step);
      propagate(step);
    }
    return;
  }
  steps_.reserve(steps_.size() + next.steps_.size());
  for (const Step& step : next.steps_) {
    steps_.push_back(step);
    propagate(step);
  }
  shift_end_s_ = next.shift_end_s_;  // the union ends where `next` does
}

Preintegrated Preintegrated::merged(const Preintegrated& first, const Preintegrated& second) {
  Preintegrated out = first;
  out.append(second);
  return out;
}

void Preintegrated::moveBoundary(Preintegrated& earlier, Preintegrated& later, double new_shift_s) {
  const double move_s = new_shift_s - earlier.shift_end_s_;  // > 0: the boundary moves later in time
  if (move_s == 0.0) {
    later.shift_begin_s_ = new_shift_s;
    return;
  }
  Preintegrated& giver = move_s > 0.0 ? later : earlier;
  Preintegrated& taker = move_s > 0.0 ? earlier : later;
  double remaining = std::abs(move_s);
  LTLO_ASSERT(remaining < giver.dt_s_, "moving an IMU boundary by " << move_s << " s across a " << giver.dt_s_
                                                                    << " s preintegration");
  std::vector<Step> handed;  // in time order
  if (move_s > 0.0) {
    // From the front of `later` to the back of `earlier`.
    std::size_t k = 0;
    while (remaining > 0.0 && k < giver.steps_.size()) {
      Step& step = giver.steps_[k];
      if (step.dt_s <= remaining) {
        handed.push_back(step);
        remaining -= step.dt_s;
        ++k;
      } else {
        Step piece = step;
        piece.dt_s = remaining;
        step.dt_s -= remaining;
        handed.push_back(piece);
        remaining = 0.0;
      }
    }
    giver.steps_.erase(giver.steps_.begin(), giver.steps_.begin() + static_cast<std::ptrdiff_t>(k));
    taker.steps_.insert(taker.steps_.end(), handed.begin(), handed.end());
  } else {
    // From the back of `earlier` to the front of `later`.
    std::size_t k = giver.steps_.size();
    while (remaining > 0.0 && k > 0) {
      Step& step = giver.steps_[k - 1];
      if (step.dt_s <= remaining) {
        handed.insert(handed.begin(), step);
        remaining -= step.dt_s;
        --k;
      } else {
        Step piece = step;
        piece.dt_s = remaining;
        step.dt_s -= remaining;
        handed.insert(handed.begin(), piece);
        remaining = 0.0;
      }
    }
    giver.steps_.resize(k);
    taker.steps_.insert(taker.steps_.begin(), handed.begin(), handed.end());
  }
  earlier.shift_end_s_ = new_shift_s;
  later.shift_begin_s_ = new_shift_s;
  earlier.reintegrate(earlier.bias_);
  later.reintegrate(later.bias_);
}

Mat9 Preintegrated::information() const {
  LTLO_ASSERT(dt_s_ > 0.0, "information of an empty preintegration");
  return covariance_.ldlt().solve(Mat9::Identity());
}

Mat3 Preintegrated::correctedDeltaR(const ImuBias& new_bias) const {
  return normalizeRotation(delta_R_ * so3Exp(d_R_d_b_g_ * (new_bias.b_g - bias_.b_g)));
}

Vec3 Preintegrated::correctedDeltaV(const ImuBias& new_bias) const {
  return delta_v_ + d_v_d_b_g_ * (new_bias.b_g - bias_.b_g) + d_v_d_b_a_ * (new_bias.b_a - bias_.b_a);
}

Vec3 Preintegrated::correctedDeltaP(const ImuBias& new_bias) const {
  return delta_p_ + d_p_d_b_g_ * (new_bias.b_g - bias_.b_g) + d_p_d_b_a_ * (new_bias.b_a - bias_.b_a);
}

}  // namespace ltlo::imu
