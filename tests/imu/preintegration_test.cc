#include "ltlo/imu/preintegration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/analytic_trajectory.h"
#include "ltlo/core/assert.h"
#include "ltlo/core/lie.h"
#include "ltlo/imu/imu_types.h"
#include "numeric_jacobian.h"

namespace ltlo::imu {
namespace {

using test::AnalyticTrajectory;
using test::numericJacobian;

constexpr double kRateHz = 200.0;
constexpr double kRadToDeg = 180.0 / M_PI;

ImuNoise testNoise() {
  ImuCalib calib;
  calib.rate_hz = kRateHz;
  return ImuNoise::fromCalib(calib);
}

Preintegrated preintegrate(const std::vector<ImuSample>& samples, const ImuBias& bias) {
  Preintegrated pim(bias, testNoise());
  pim.integrate(samples);
  return pim;
}

TEST(ImuNoise, DiscreteCovariancesFromDensities) {
  ImuCalib calib;
  calib.noise_gyro = 2e-4;
  calib.noise_acc = 3e-3;
  calib.gyro_walk = 4e-5;
  calib.acc_walk = 5e-3;
  calib.rate_hz = 400.0;
  const ImuNoise noise = ImuNoise::fromCalib(calib);
  EXPECT_DOUBLE_EQ(noise.nominal_dt_s, 0.0025);
  EXPECT_NEAR(noise.gyroCovariance()(1, 1), 2e-4 * 2e-4 * 400.0, 1e-18);   // sigma^2 / dt
  EXPECT_NEAR(noise.accCovariance()(2, 2), 3e-3 * 3e-3 * 400.0, 1e-15);
  EXPECT_DOUBLE_EQ(noise.gyroCovariance()(0, 1), 0.0);
  const Mat6 walk = noise.biasWalkCovariance(2.0);                          // sigma_w^2 * T
  EXPECT_NEAR(walk(0, 0), 4e-5 * 4e-5 * 2.0, 1e-20);
  EXPECT_NEAR(walk(5, 5), 5e-3 * 5e-3 * 2.0, 1e-18);
}

TEST(ImuSamples, IntervalHasInterpolatedEndsAndKeepsGridSamples) {
  const AnalyticTrajectory traj;
  const std::vector<ImuSample> grid = traj.samples(0.0, 1.0, kRateHz);
  const std::vector<ImuSample> inside = samplesInInterval(grid, 0.1234, 0.5678);
  ASSERT_GE(inside.size(), 2u);
  EXPECT_DOUBLE_EQ(inside.front().t_s, 0.1234);
  EXPECT_DOUBLE_EQ(inside.back().t_s, 0.5678);
  // 0.125 .. 0.565 on the 5 ms grid = 89 samples, plus the two ends.
  EXPECT_EQ(inside.size(), 91u);
  // Interpolated gyro reading at 0.1234 lies between its neighbours (linear in time).
  const ImuSample expected = interpolateImuSample(grid[24], grid[25], 0.1234);
  EXPECT_LT((inside.front().gyro_rad_s - expected.gyro_rad_s).norm(), 1e-15);
  // Ends on the grid are not duplicated.
  const std::vector<ImuSample> on_grid = samplesInInterval(grid, 0.1, 0.2);
  EXPECT_EQ(on_grid.size(), 21u);
  EXPECT_THROW(samplesInInterval(grid, 0.5, 1.5), AssertionError);
}

// Noise-free IMU from the analytic trajectory reproduces the ground-truth relative motion.
TEST(ImuPreintegration, NoiseFreeReproducesGroundTruthRelativeMotion) {
  const AnalyticTrajectory traj;
  const ImuBias bias{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
  const std::vector<ImuSample> grid = traj.samples(0.0, 2.0, kRateHz, bias);
  for (const auto& [t_i, t_j] : {std::pair{0.3, 1.3}, std::pair{0.4123, 0.9377}}) {
    const Preintegrated pim = preintegrate(samplesInInterval(grid, t_i, t_j), bias);
    const NavState s_i = traj.state(t_i);
    const NavState s_j = traj.state(t_j);
    const double dt = t_j - t_i;
    EXPECT_NEAR(pim.dt_s(), dt, 1e-12);
    const Mat3 R_i_T = s_i.R_w_b.transpose();
    const Mat3 dR_true = R_i_T * s_j.R_w_b;
    const Vec3 dv_true = R_i_T * (s_j.v_w_b - s_i.v_w_b - gravityWorld() * dt);
    const Vec3 dp_true =
        R_i_T * (s_j.p_w_b - s_i.p_w_b - s_i.v_w_b * dt - 0.5 * dt * dt * gravityWorld());
    const double rot_err_deg = so3Log(Mat3(dR_true.transpose() * pim.deltaR())).norm() * kRadToDeg;
    const double vel_err = (pim.deltaV() - dv_true).norm();
    const double pos_err = (pim.deltaP() - dp_true).norm();
    EXPECT_LT(rot_err_deg, 0.01) << dt;
    EXPECT_LT(pos_err, 1e-3) << dt;
    EXPECT_LT(vel_err, 1e-3) << dt;
    // Measured on this trajectory (midpoint scheme, second order): a few 1e-6 in all three.
    EXPECT_LT(rot_err_deg, 1e-4) << dt;
    EXPECT_LT(pos_err, 1e-5) << dt;

    // The prediction from the true state at i lands on the true state at j.
    const NavState predicted = predict(s_i, pim, bias, gravityWorld());
    EXPECT_LT((predicted.p_w_b - s_j.p_w_b).norm(), 1e-3);
    EXPECT_LT((predicted.v_w_b - s_j.v_w_b).norm(), 1e-3);
    EXPECT_LT(so3Log(Mat3(predicted.R_w_b.transpose() * s_j.R_w_b)).norm() * kRadToDeg, 0.01);
  }
}

// Bias Jacobians against re-preintegration with a perturbed bias (central differences; the
// rotation is compared through the right-perturbation log Log(dR0^T dR(b))).
TEST(ImuPreintegration, BiasJacobiansMatchNumericDifferentiation) {
  const AnalyticTrajectory traj;
  const ImuBias bias{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
  const std::vector<ImuSample> samples = samplesInInterval(traj.samples(0.0, 2.0, kRateHz), 0.3, 1.2);
  const Preintegrated pim = preintegrate(samples, bias);
  Preintegrated perturbed = pim;

  auto deltas_with_gyro_bias = [&](const Vec3& d) {
    ImuBias b = bias;
    b.b_g += d;
    perturbed.reintegrate(b);
    Vec9 out;
    out << so3Log(Mat3(pim.deltaR().transpose() * perturbed.deltaR())), perturbed.deltaV(),
        perturbed.deltaP();
    return out;
  };
  auto deltas_with_acc_bias = [&](const Vec3& d) {
    ImuBias b = bias;
    b.b_a += d;
    perturbed.reintegrate(b);
    Vec9 out;
    out << so3Log(Mat3(pim.deltaR().transpose() * perturbed.deltaR())), perturbed.deltaV(),
        perturbed.deltaP();
    return out;
  };
  const Eigen::Matrix<double, 9, 3> num_g = numericJacobian<9, 3>(deltas_with_gyro_bias);
  const Eigen::Matrix<double, 9, 3> num_a = numericJacobian<9, 3>(deltas_with_acc_bias);

  EXPECT_LT((num_g.topRows<3>() - pim.d_R_d_b_g()).norm(), 1e-7 * pim.d_R_d_b_g().norm());
  EXPECT_LT((num_g.middleRows<3>(3) - pim.d_v_d_b_g()).norm(), 1e-7 * pim.d_v_d_b_g().norm());
  EXPECT_LT((num_g.bottomRows<3>() - pim.d_p_d_b_g()).norm(), 1e-7 * pim.d_p_d_b_g().norm());
  EXPECT_LT(num_a.topRows<3>().norm(), 1e-9);  // the accelerometer bias does not rotate
  EXPECT_LT((num_a.middleRows<3>(3) - pim.d_v_d_b_a()).norm(), 1e-7 * pim.d_v_d_b_a().norm());
  EXPECT_LT((num_a.bottomRows<3>() - pim.d_p_d_b_a()).norm(), 1e-7 * pim.d_p_d_b_a().norm());
  // Magnitudes over 0.9 s: |d_v_d_b_a| = |sum R_m dt| <= sqrt(3) 0.9 (equal without rotation).
  EXPECT_GT(pim.d_v_d_b_a().norm() / std::sqrt(3.0), 0.85);
  EXPECT_LE(pim.d_v_d_b_a().norm() / std::sqrt(3.0), 0.9);
}

// First-order correction for a small bias change is much closer to re-integration than the
// uncorrected deltas.
TEST(ImuPreintegration, FirstOrderBiasCorrectionApproximatesReintegration) {
  const AnalyticTrajectory traj;
  const ImuBias bias0{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
  const std::vector<ImuSample> samples = samplesInInterval(traj.samples(0.0, 2.0, kRateHz), 0.3, 1.3);
  const Preintegrated pim = preintegrate(samples, bias0);
  ImuBias bias1 = bias0;
  bias1.b_g += Vec3(0.004, -0.003, 0.005);
  bias1.b_a += Vec3(-0.05, 0.04, 0.03);
  Preintegrated exact = pim;
  exact.reintegrate(bias1);
  EXPECT_EQ(exact.bias().b_g, bias1.b_g);

  const double rot_uncorrected = so3Log(Mat3(exact.deltaR().transpose() * pim.deltaR())).norm();
  const double rot_corrected =
      so3Log(Mat3(exact.deltaR().transpose() * pim.correctedDeltaR(bias1))).norm();
  const double vel_uncorrected = (exact.deltaV() - pim.deltaV()).norm();
  const double vel_corrected = (exact.deltaV() - pim.correctedDeltaV(bias1)).norm();
  const double pos_uncorrected = (exact.deltaP() - pim.deltaP()).norm();
  const double pos_corrected = (exact.deltaP() - pim.correctedDeltaP(bias1)).norm();
  EXPECT_GT(rot_uncorrected, 5e-3);
  EXPECT_GT(pos_uncorrected, 2e-2);
  EXPECT_LT(rot_corrected, 1e-3 * rot_uncorrected);
  EXPECT_LT(vel_corrected, 1e-2 * vel_uncorrected);
  EXPECT_LT(pos_corrected, 1e-2 * pos_uncorrected);
  // Correcting to the linearisation bias changes nothing.
  EXPECT_LT((pim.correctedDeltaP(bias0) - pim.deltaP()).norm(), 1e-15);
}

// Merge of two consecutive preintegrations equals the preintegration over the union.
TEST(ImuPreintegration, MergeEqualsPreintegrationOverUnion) {
  const AnalyticTrajectory traj;
  const ImuBias bias{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
  std::mt19937 rng(7);
  const ImuNoise noise = testNoise();
  const std::vector<ImuSample> grid = traj.samples(0.0, 2.0, kRateHz, bias, &noise, &rng);
  const double t_i = 0.3012, t_k = 0.8123, t_j = 1.2987;
  const std::vector<ImuSample> first = samplesInInterval(grid, t_i, t_k);
  const std::vector<ImuSample> second = samplesInInterval(grid, t_k, t_j);
  std::vector<ImuSample> union_samples = first;
  union_samples.insert(union_samples.end(), second.begin() + 1, second.end());

  const Preintegrated pim_first = preintegrate(first, bias);
  ImuBias other_bias = bias;  // the second interval was linearised elsewhere: merge re-linearises
  other_bias.b_g += Vec3(0.003, 0.0, -0.002);
  const Preintegrated pim_second = preintegrate(second, other_bias);
  const Preintegrated merged = Preintegrated::merged(pim_first, pim_second);
  const Preintegrated whole = preintegrate(union_samples, bias);

  EXPECT_NEAR(merged.dt_s(), t_j - t_i, 1e-12);
  EXPECT_EQ(merged.numSteps(), whole.numSteps());
  EXPECT_LT((merged.deltaR() - whole.deltaR()).norm(), 1e-12);
  EXPECT_LT((merged.deltaV() - whole.deltaV()).norm(), 1e-12);
  EXPECT_LT((merged.deltaP() - whole.deltaP()).norm(), 1e-12);
  EXPECT_LT((merged.covariance() - whole.covariance()).norm(), 1e-12 * whole.covariance().norm());
  EXPECT_LT((merged.d_p_d_b_g() - whole.d_p_d_b_g()).norm(), 1e-12);
  EXPECT_LT((merged.d_v_d_b_a() - whole.d_v_d_b_a()).norm(), 1e-12);
  EXPECT_EQ(merged.bias().b_g, bias.b_g);

  // Also the composition law of the deltas: dR = dR1 dR2, dv = dv1 + dR1 dv2,
  // dp = dp1 + dv1 dt2 + dR1 dp2 (second interval re-linearised at the first's bias).
  Preintegrated second_at_bias = pim_second;
  second_at_bias.reintegrate(bias);
  const Vec3 dp_composed = pim_first.deltaP() + pim_first.deltaV() * second_at_bias.dt_s() +
                           pim_first.deltaR() * second_at_bias.deltaP();
  EXPECT_LT((dp_composed - merged.deltaP()).norm(), 1e-12);
}

// Tracking appends one frame's preintegration at a time (each linearised at the bias of its day):
// the chain equals one preintegration over all samples at the first bias, and appending an
// interval to itself doubles it.
TEST(ImuPreintegration, FrameByFrameAppendEqualsPreintegrationOverUnion) {
  const AnalyticTrajectory traj;
  const ImuBias bias{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
  std::mt19937 rng(11);
  const ImuNoise noise = testNoise();
  const std::vector<ImuSample> grid = traj.samples(0.0, 3.0, kRateHz, bias, &noise, &rng);
  const double t_begin = 0.1001, frame_dt = 1.0 / 30.0;
  Preintegrated chain(bias, noise);
  double t = t_begin;
  for (int frame = 0; frame < 60; ++frame, t += frame_dt) {
    ImuBias frame_bias = bias;
    frame_bias.b_a += Vec3(1e-3 * frame, 0.0, -5e-4 * frame);  // the tracker's bias moves on
    chain.append(preintegrate(samplesInInterval(grid, t, t + frame_dt), frame_bias));
  }
  std::vector<ImuSample> union_samples;
  double t_union = t_begin;
  for (int frame = 0; frame < 60; ++frame, t_union += frame_dt) {
    const std::vector<ImuSample> part = samplesInInterval(grid, t_union, t_union + frame_dt);
    union_samples.insert(union_samples.end(), part.begin() + (union_samples.empty() ? 0 : 1), part.end());
  }
  const Preintegrated whole = preintegrate(union_samples, bias);
  EXPECT_EQ(chain.numSteps(), whole.numSteps());
  EXPECT_NEAR(chain.dt_s(), whole.dt_s(), 1e-12);
  EXPECT_LT((chain.deltaR() - whole.deltaR()).norm(), 1e-12);
  EXPECT_LT((chain.deltaV() - whole.deltaV()).norm(), 1e-11);
  EXPECT_LT((chain.deltaP() - whole.deltaP()).norm(), 1e-11);
  EXPECT_LT((chain.covariance() - whole.covariance()).norm(), 1e-10 * whole.covariance().norm());
  EXPECT_LT((chain.d_p_d_b_a() - whole.d_p_d_b_a()).norm(), 1e-11);
  EXPECT_LT((chain.d_v_d_b_g() - whole.d_v_d_b_g()).norm(), 1e-11);

  Preintegrated doubled = preintegrate(samplesInInterval(grid, 0.5, 0.6), bias);
  const int steps = doubled.numSteps();
  doubled.append(doubled);
  EXPECT_EQ(doubled.numSteps(), 2 * steps);
  EXPECT_NEAR(doubled.dt_s(), 0.2, 1e-12);
}

// The propagated covariance is exactly sum_k J_k N_k J_k^T, where J_k is the numeric Jacobian of
// the final deltas [Log(dR0^T dR), dv, dp] w.r.t. the readings of step k and N_k the step's noise
// covariance (checks the linearisation, independently of sampling noise).
TEST(ImuPreintegration, CovarianceEqualsSumOfNumericNoiseJacobians) {
  const AnalyticTrajectory traj;
  const ImuBias bias{Vec3(0.01, -0.02, 0.015), Vec3(0.1, -0.05, 0.08)};
  const ImuNoise noise = testNoise();
  const std::vector<ImuSample> samples =
      samplesInInterval(traj.samples(0.0, 1.0, kRateHz, bias), 0.3012, 0.4987);  // 40 steps
  const Preintegrated pim = preintegrate(samples, bias);
  ASSERT_EQ(pim.numSteps(), 40);

  Mat9 expected = Mat9::Zero();
  for (size_t step = 1; step < samples.size(); ++step) {
    const double dt = samples[step].t_s - samples[step - 1].t_s;
    const Vec3 gyro_mean = 0.5 * (samples[step - 1].gyro_rad_s + samples[step].gyro_rad_s);
    const Vec3 acc_mean = 0.5 * (samples[step - 1].acc_m_s2 + samples[step].acc_m_s2);
    auto deltas_with_reading_change = [&](const Vec6& d) {
      Preintegrated p(bias, noise);
      for (size_t k = 1; k < samples.size(); ++k) {
        if (k == step) {
          p.integrateStep(gyro_mean + d.head<3>(), acc_mean + d.tail<3>(), dt);
        } else {
          p.integrate(samples[k - 1], samples[k]);
        }
      }
      Vec9 out;
      out << so3Log(Mat3(pim.deltaR().transpose() * p.deltaR())), p.deltaV(), p.deltaP();
      return out;
    };
    const Eigen::Matrix<double, 9, 6> J = numericJacobian<9, 6>(deltas_with_reading_change);
    Mat6 step_cov = Mat6::Zero();
    step_cov.topLeftCorner<3, 3>() = noise.gyroCovariance(dt);
    step_cov.bottomRightCorner<3, 3>() = noise.accCovariance(dt);
    expected += J * step_cov * J.transpose();
  }
  for (int r = 0; r < 9; ++r) {
    for (int c = 0; c < 9; ++c) {
      const double scale = std::sqrt(expected(r, r) * expected(c, c));
      EXPECT_NEAR(pim.covariance()(r, c), expected(r, c), 1e-6 * scale) << r << ", " << c;
    }
  }
}

// Covariance propagation against Monte-Carlo: 1000 runs of 0.5 s of noisy 200 Hz samples (white
// noise of the discrete per-sample covariance, densities 10x the defaults). Tolerance: whitened by
// the predicted covariance, the sample covariance is the identity within 0.2 per element (the
// standard error of one element is ~0.032 off the diagonal, ~0.045 on it, for 1000 runs).
TEST(ImuPreintegration, CovarianceMatchesMonteCarlo) {
  const AnalyticTrajectory traj;
  ImuCalib calib;
  calib.rate_hz = kRateHz;
  calib.noise_gyro *= 10.0;
  calib.noise_acc *= 10.0;
  const ImuNoise noise = ImuNoise::fromCalib(calib);
  const ImuBias bias;
  const double t_i = 0.3, t_j = 0.8;
  const std::vector<ImuSample> clean = traj.samples(t_i, t_j, kRateHz);
  Preintegrated reference(bias, noise);
  reference.integrate(clean);

  constexpr int kRuns = 1000;
  std::mt19937 rng(42);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double sigma_g = std::sqrt(noise.gyroCovariance()(0, 0));  // per-sample standard deviations
  const double sigma_a = std::sqrt(noise.accCovariance()(0, 0));
  Mat9 sample_cov = Mat9::Zero();
  std::vector<ImuSample> noisy = clean;
  for (int run = 0; run < kRuns; ++run) {
    for (size_t k = 0; k < clean.size(); ++k) {
      const Vec3 n_g(normal(rng), normal(rng), normal(rng));
      const Vec3 n_a(normal(rng), normal(rng), normal(rng));
      noisy[k].gyro_rad_s = clean[k].gyro_rad_s + sigma_g * n_g;
      noisy[k].acc_m_s2 = clean[k].acc_m_s2 + sigma_a * n_a;
    }
    Preintegrated pim(bias, noise);
    pim.integrate(noisy);
    Vec9 err;
    err << so3Log(Mat3(reference.deltaR().transpose() * pim.deltaR())),
        pim.deltaV() - reference.deltaV(), pim.deltaP() - reference.deltaP();
    sample_cov += err * err.transpose();
  }
  sample_cov /= kRuns;

  const Mat9& predicted = reference.covariance();
  const Eigen::LLT<Mat9> llt(predicted);
  ASSERT_EQ(llt.info(), Eigen::Success);
  const Mat9 L_inv = llt.matrixL().solve(Mat9::Identity());
  const Mat9 whitened = L_inv * sample_cov * L_inv.transpose();
  const double max_dev = (whitened - Mat9::Identity()).cwiseAbs().maxCoeff();
  EXPECT_LT(max_dev, 0.2) << "whitened sample covariance\n" << whitened;
  for (int k = 0; k < 9; ++k) {
    const double ratio = sample_cov(k, k) / predicted(k, k);
    EXPECT_GT(ratio, 0.85) << k;
    EXPECT_LT(ratio, 1.15) << k;
  }
  // Rough magnitude: the rotation variance is sigma_g^2 T per axis (rotation noise only).
  EXPECT_NEAR(predicted(0, 0), calib.noise_gyro * calib.noise_gyro * 0.5, 1e-3 * predicted(0, 0));
}

// Two samples 0.5 s apart (an IMU gap integrated across): 25 sub-steps of 20 ms with the same
// mean reading, so the covariance is positive definite (a single step's has rank 6 of 9) and the
// deltas are those of the constant reading.
TEST(ImuPreintegration, GapBetweenTwoSamplesIsSplitAndHasAFullRankCovariance) {
  Preintegrated pim(ImuBias(), testNoise());
  ImuSample a, b;
  a.t_s = 10.0;
  b.t_s = 10.5;
  a.acc_m_s2 = b.acc_m_s2 = Vec3(0.0, 0.0, kGravity_m_s2);
  pim.integrate({a, b});
  EXPECT_EQ(pim.numSteps(), 25);
  EXPECT_NEAR(pim.dt_s(), 0.5, 1e-12);
  EXPECT_NEAR(pim.deltaP().z(), 0.5 * kGravity_m_s2 * 0.25, 1e-9);
  const Eigen::LLT<Mat9> llt(pim.covariance());
  EXPECT_EQ(llt.info(), Eigen::Success);
  // One 5 ms step of a 200 Hz IMU is not split.
  Preintegrated single(ImuBias(), testNoise());
  b.t_s = 10.005;
  single.integrate({a, b});
  EXPECT_EQ(single.numSteps(), 1);
}

TEST(ImuPreintegration, ZeroStepIgnoredNegativeStepAsserts) {
  Preintegrated pim(ImuBias(), testNoise());
  pim.integrateStep(Vec3(0.1, 0.0, 0.0), Vec3(0.0, 0.0, 9.81), 0.0);
  EXPECT_EQ(pim.numSteps(), 0);
  EXPECT_DOUBLE_EQ(pim.dt_s(), 0.0);
  EXPECT_THROW(pim.integrateStep(Vec3::Zero(), Vec3::Zero(), -0.001), AssertionError);
  // At rest with z up: delta_v = g_up * dt cancels gravity in the residual convention.
  pim.integrateStep(Vec3::Zero(), Vec3(0.0, 0.0, kGravity_m_s2), 0.5);
  EXPECT_NEAR(pim.deltaV().z(), kGravity_m_s2 * 0.5, 1e-12);
  EXPECT_NEAR(pim.deltaP().z(), 0.5 * kGravity_m_s2 * 0.25, 1e-12);
}

}  // namespace
}  // namespace ltlo::imu
