#pragma once
/// On-manifold IMU preintegration (Forster et al., "On-Manifold Preintegration for Real-Time
/// Visual-Inertial Odometry", T-RO 2017) with bias Jacobians, covariance propagation and
/// first-order bias correction.
///
/// Deltas between keyframes i and j, independent of the state at i (body frame of i):
///   delta_R = R_i^T R_j,  delta_v = R_i^T (v_j - v_i - g dt),  delta_p = R_i^T (p_j - p_i - v_i dt - g dt^2 / 2).
///
/// Integration scheme (midpoint, second order): each step between consecutive samples k, k+1 uses
/// the averaged measurements w = (w_k + w_k+1)/2 - b_g, a = (a_k + a_k+1)/2 - b_a and the rotation at
/// mid-step R_m = delta_R_k Exp(w dt/2):
///   delta_p += delta_v dt + R_m a dt^2 / 2,  delta_v += R_m a dt,  delta_R = delta_R Exp(w dt).
/// The bias Jacobians and the covariance are the exact linearisation of this scheme. The step noise
/// is modelled as white with the discrete covariance of ImuNoise over the step's dt (the correlation
/// introduced by averaging neighbouring samples is neglected; it changes the integrated variance by
/// about half a step at each end).
///
/// Error conventions: rotation errors are right perturbations (delta_R_true = delta_R Exp(phi)); the
/// covariance is 9x9 in the order [phi, v, p].
///
/// Camera-IMU time shift: the interval integrated between the frames at camera times t_i and t_j is
/// [t_i + shift_begin, t_j + shift_end] on the IMU's clock (after the reader applied IMU.TimeOffset),
/// where the shifts are the online estimate of the remaining offset when each end was cut. The deltas
/// then describe the motion between the two images if the shifts are right; moveBoundary() moves
/// the end shared by two consecutive preintegrations when the estimate changes, exactly, by handing
/// steps from one to the other.
#include <vector>

#include "ltlo/core/eigen_types.h"
#include "ltlo/imu/imu_types.h"

namespace ltlo::imu {

class Preintegrated {
 public:
  /// Empty preintegration (identity deltas, dt = 0) linearised at `bias`.
  Preintegrated(const ImuBias& bias, const ImuNoise& noise);

  /// Integrates one step of dt_s between two samples, given their averaged raw readings.
  /// dt_s == 0 is ignored (duplicate end samples); dt_s < 0 asserts.
  void integrateStep(const Vec3& gyro_mean_rad_s, const Vec3& acc_mean_m_s2, double dt_s);
  /// Integrates the step from sample a to sample b (b.t_s >= a.t_s).
  void integrate(const ImuSample& a, const ImuSample& b);
  /// Integrates all consecutive pairs: exactly [samples.front().t_s, samples.back().t_s]. Give
  /// samples with interpolated ends (samplesInInterval) to cover a keyframe interval exactly.
  void integrate(const std::vector<ImuSample>& samples);

  /// Integrates all stored steps again with a new linearisation bias (exact, resets the Jacobians).
  void reintegrate(const ImuBias& new_bias);
  /// Appends `next` (the interval that starts where this one ends): its raw steps are integrated
  /// on at this preintegration's bias, so the result equals a preintegration over the union of the
  /// samples (whatever bias `next` was linearised at). Costs O(next.numSteps()), independent of the
  /// interval already held. The end's time shift becomes `next`'s.
  void append(const Preintegrated& next);
  /// Merge of two consecutive preintegrations (keyframe culling); `first`'s bias is kept.
  static Preintegrated merged(const Preintegrated& first, const Preintegrated& second);

  /// The time shifts of the two ends (s; see the file comment): 0 unless set.
  double shiftBegin_s() const { return shift_begin_s_; }
  double shiftEnd_s() const { return shift_end_s_; }
  void setShifts(double begin_s, double end_s) {
    shift_begin_s_ = begin_s;
    shift_end_s_ = end_s;
  }
  /// Moves the boundary between two consecutive preintegrations (earlier.shiftEnd_s() ==
  /// later.shiftBegin_s()) to `new_shift_s`: the steps between the old and the new boundary pass
  /// from one to the other (a step cut in two keeps its readings on both sides), and both are
  /// integrated again at their own biases. Asserts that the piece handed over is shorter than the
  /// giving side.
  static void moveBoundary(Preintegrated& earlier, Preintegrated& later, double new_shift_s);
  /// Bias-free mean gyro reading of the first / last step (rad/s; zero without steps): the angular
  /// rate at the ends, which a shift of the end rotates the delta by (d delta_R / d shift).
  Vec3 firstGyro() const { return steps_.empty() ? Vec3::Zero() : steps_.front().gyro_mean_rad_s; }
  Vec3 lastGyro() const { return steps_.empty() ? Vec3::Zero() : steps_.back().gyro_mean_rad_s; }

  const ImuBias& bias() const { return bias_; }
  const ImuNoise& noise() const { return noise_; }
  double dt_s() const { return dt_s_; }
  int numSteps() const { return static_cast<int>(steps_.size()); }

  const Mat3& deltaR() const { return delta_R_; }
  const Vec3& deltaV() const { return delta_v_; }
  const Vec3& deltaP() const { return delta_p_; }
  /// Covariance of [phi, v, p] (rad, m/s, m).
  const Mat9& covariance() const { return covariance_; }
  /// Information matrix: the inverse of covariance() (asserts dt > 0).
  Mat9 information() const;

  /// First-order bias Jacobians at bias(): delta_R(b) ~ delta_R Exp(d_R_d_b_g (b_g - b_g0)), etc.
  const Mat3& d_R_d_b_g() const { return d_R_d_b_g_; }
  const Mat3& d_v_d_b_g() const { return d_v_d_b_g_; }
  const Mat3& d_v_d_b_a() const { return d_v_d_b_a_; }
  const Mat3& d_p_d_b_g() const { return d_p_d_b_g_; }
  const Mat3& d_p_d_b_a() const { return d_p_d_b_a_; }

  /// Deltas corrected to first order for a bias `new_bias` near bias().
  Mat3 correctedDeltaR(const ImuBias& new_bias) const;
  Vec3 correctedDeltaV(const ImuBias& new_bias) const;
  Vec3 correctedDeltaP(const ImuBias& new_bias) const;

  /// One integration step as received (raw averaged readings, before bias removal).
  struct Step {
    Vec3 gyro_mean_rad_s;
    Vec3 acc_mean_m_s2;
    double dt_s;
  };
  /// The raw steps held, in time order: a preintegration at the same bias and noise that
  /// integrateStep()s them in this order and takes the same shifts equals this one bit for bit
  /// (the state is a sequential function of them; the atlas file stores them so).
  const std::vector<Step>& steps() const { return steps_; }

 private:
  void reset();
  void propagate(const Step& step);

  ImuBias bias_;
  ImuNoise noise_;
  std::vector<Step> steps_;
  double shift_begin_s_ = 0.0;
  double shift_end_s_ = 0.0;

  double dt_s_ = 0.0;
  Mat3 delta_R_;
  Vec3 delta_v_;
  Vec3 delta_p_;
  Mat9 covariance_;
  Mat3 d_R_d_b_g_;
  Mat3 d_v_d_b_g_;
  Mat3 d_v_d_b_a_;
  Mat3 d_p_d_b_g_;
  Mat3 d_p_d_b_a_;
};

}  // namespace ltlo::imu
